// The CUDA backend against the 2-thread CPU path on the same graphs (real kitti07 clouds, ~20k points
// per factor): batched linearization and trial evaluation per LM iteration for up to 4,500 factors
// (the paper's KITTI 00 final graph), point evaluations per second, overlap per pair, a scan's
// covariances, device bytes.
// Not a test: prints "skipped" without a GPU or without ../shared/data.
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>

#include <cstdio>

#include "gcmap/core/preprocess.hpp"
#include "gcmap/core/timer.hpp"
#include "gcmap/cuda/cuda_backend.hpp"
#include "gcmap/graph/levenberg_marquardt.hpp"
#include "kitti07_graph.hpp"

using namespace gcmap;

namespace {

// Batched linearization against the CPU, then a full LM run on the GPU, per graph size.
void bench_graphs(const bench::Kitti07& data, const std::shared_ptr<cuda::CudaBackend>& gpu) {
  for (int num_factors : {10, 100, 1000, 4500}) {
    FactorGraph graph;
    Values values;
    data.make_graph(num_factors, graph, values);
    const double evaluations = static_cast<double>(num_factors) * data.points_per_cloud;
    const bench::Timing g = bench::time_backend(*gpu, graph, values, 20);
    bench::Timing c;
    {
      tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 2);
      CpuBackend cpu;
      c = bench::time_backend(cpu, graph, values, num_factors >= 1000 ? 1 : 3);
    }
    std::printf(
        "factors=%4d  GPU linearize %.2f ms (%.2f G point evaluations/s), trial %.2f ms | CPU 2 threads linearize %.1f ms, trial "
        "%.1f ms | speed-up %.0fx\n",
        num_factors, g.linearize_ms, evaluations / (g.linearize_ms / 1000.0) / 1e9, g.trial_ms, c.linearize_ms, c.trial_ms,
        c.linearize_ms / g.linearize_ms);
    // A full LM run on the GPU from poses off by ~0.1 m / 0.3 deg (steps get accepted, as in mapping),
    // 5 iterations, no early stop; iteration 1 includes the symbolic analysis.
    LMConfig config;
    config.max_iterations = 5;
    config.relative_error_tol = 0.0;
    config.step_tol = 0.0;
    Values vals = bench::perturbed(values, 0.1, 0.005);
    const LMResult r = LevenbergMarquardt(config, gpu).optimize(graph, vals, {0});
    std::printf("              LM on the GPU, ms per iteration (trials): total = linearize+evaluate + assemble + solve\n");
    for (const LMIteration& it : r.history)
      std::printf("                %d: %.2f (%d) = %.2f + %.2f + %.2f\n", it.iteration,
                  it.linearize_ms + it.assemble_ms + it.solve_ms, it.trials, it.linearize_ms, it.assemble_ms, it.solve_ms);
    std::printf("              mean %.2f ms/iteration over %d (whole optimize() call)\n", r.total_ms / r.iterations,
                r.iterations);
  }
}

// One registration (the odometry's call): cloud 1 onto cloud 0's voxels from a guess 0.3 m off.
void bench_registration(const bench::Kitti07& data, cuda::CudaBackend& gpu) {
  const std::vector<ScanNode>& nodes = data.nodes;
  const Eigen::Isometry3d truth = data.reference.poses[0].inverse() * data.reference.poses[1];
  const Eigen::Isometry3d guess = truth * Eigen::Translation3d(0.3, -0.2, 0.1);
  RegistrationConfig config;
  config.max_iterations = 32;
  RegistrationResult g = gpu.align(*nodes[1].cloud, nodes[0].voxels, guess, config);  // warm-up: the target's upload
  Stopwatch w;
  for (int r = 0; r < 20; ++r) g = gpu.align(*nodes[1].cloud, nodes[0].voxels, guess, config);
  const double gpu_ms = w.ms() / 20;
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 2);
  CpuBackend cpu;
  w.lap_ms();
  const RegistrationResult c = cpu.align(*nodes[1].cloud, nodes[0].voxels, guess, config);
  const double cpu_ms = w.ms();
  std::printf(
      "registration (%zu points, %d iterations): GPU %.2f ms (source upload included) | CPU 2 threads %.1f ms | results %.2g m "
      "apart\n",
      nodes[1].cloud->size(), g.iterations, gpu_ms, cpu_ms,
      (g.T_target_source.translation() - c.T_target_source.translation()).norm());
}

// Overlap of one source against many targets in one launch.
void bench_overlaps(const bench::Kitti07& data, cuda::CudaBackend& gpu) {
  const std::vector<ScanNode>& nodes = data.nodes;
  for (int num_targets : {4, 100, 1000}) {
    std::vector<std::shared_ptr<const GaussianVoxelMap>> targets;
    std::vector<Eigen::Isometry3d> T;
    for (int k = 0; k < num_targets; ++k) {
      targets.push_back(nodes[1 + k % 4].voxels);
      T.push_back(data.reference.poses[1 + k % 4].inverse() * data.reference.poses[0]);
    }
    std::vector<double> out(num_targets);
    gpu.overlaps(nodes[0].cloud, targets, T, out);
    Stopwatch w;
    for (int r = 0; r < 20; ++r) gpu.overlaps(nodes[0].cloud, targets, T, out);
    const double ms = w.ms() / 20;
    std::printf("overlap: 1 source (%zu points) x %d targets: %.3f ms per launch, %.4f ms per pair\n", nodes[0].cloud->size(),
                num_targets, ms, ms / num_targets);
  }
}

// A scan's covariances (k = 10) on the device: one call alone, then 4 threads at once (the pipeline
// prepares several scans side by side, each thread in its own stream), against the CPU's kd-tree.
void bench_covariances(const bench::Kitti07& data, cuda::CudaBackend& gpu) {
  PointCloud scan;
  scan.points = data.nodes[0].cloud->points;
  CovarianceConfig config;
  config.num_neighbors = 10;
  PointCloud out = scan;
  gpu.estimate_covariances(out, config);  // warm-up: buffers
  Stopwatch w;
  for (int r = 0; r < 20; ++r) gpu.estimate_covariances(out, config);
  const double alone_ms = w.ms() / 20;
  std::vector<PointCloud> outs(4, scan);
  w.lap_ms();
  tbb::parallel_for(0, 4, [&](int t) {
    for (int r = 0; r < 20; ++r) gpu.estimate_covariances(outs[t], config);
  });
  const double together_ms = w.ms() / 80;
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 2);
  PointCloud on_cpu = scan;
  w.lap_ms();
  estimate_covariances(on_cpu, config);
  const double cpu_ms = w.ms();
  std::printf(
      "covariances (%zu points, k 10): GPU %.2f ms alone, %.2f ms per scan with 4 threads at once | CPU 2 threads %.1f ms\n",
      scan.size(), alone_ms, together_ms, cpu_ms);
}

}  // namespace

int main() {
  std::string why;
  if (!cuda::device_available(&why)) {
    std::printf("skipped: no CUDA device (%s)\n", why.c_str());
    return 0;
  }
  const std::optional<bench::Kitti07> data = bench::Kitti07::load();
  if (!data) {
    std::printf("skipped: ../shared/data/kitti07_submaps is absent\n");
    return 0;
  }
  auto gpu = std::make_shared<cuda::CudaBackend>();
  std::printf("device: %s; %zu points per factor on average\n", gpu->name().c_str(), data->points_per_cloud);
  bench_graphs(*data, gpu);
  bench_registration(*data, *gpu);
  bench_overlaps(*data, *gpu);
  bench_covariances(*data, *gpu);
  const cuda::DeviceMemory m = gpu->memory();
  std::printf(
      "device memory: %zu clouds, %zu points, %.1f bytes/point; %zu maps, %zu voxels in %zu slots, %.1f bytes/voxel (table "
      "included); batch buffers %.1f MB\n",
      m.num_clouds, m.num_points, static_cast<double>(m.cloud_bytes) / m.num_points, m.num_maps, m.num_voxels, m.num_slots,
      static_cast<double>(m.map_bytes) / m.num_voxels, m.batch_bytes / 1e6);
  return 0;
}
