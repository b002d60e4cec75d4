// The CUDA backend against the 2-thread CPU path on the same graphs (real kitti07 clouds, ~20k points
// per factor): batched linearization and trial evaluation per LM iteration for up to 4,500 factors
// (the paper's KITTI 00 final graph), point evaluations per second, overlap per pair, device bytes.
// Not a test: prints "skipped" without a GPU or without ../shared/data.
#include <tbb/global_control.h>

#include <cstdio>
#include <filesystem>

#include "gcmap/core/preprocess.hpp"
#include "gcmap/core/timer.hpp"
#include "gcmap/cuda/cuda_backend.hpp"
#include "gcmap/graph/levenberg_marquardt.hpp"
#include "gcmap/io/point_cloud_io.hpp"
#include "gcmap/io/trajectory_io.hpp"

using namespace gcmap;

namespace {

struct Timing {
  double linearize_ms = 0.0, trial_ms = 0.0;
};

Timing time_backend(LinearizationBackend& backend, const FactorGraph& graph, const Values& values, int repeats) {
  std::vector<Factor*> factors;
  std::vector<FactorPoses> poses;
  for (const auto& f : graph.factors) {
    factors.push_back(f.get());
    poses.push_back({&values.at(f->keys()[0]), &values.at(f->keys()[1])});
  }
  std::vector<FactorLinearization> lin(factors.size());
  std::vector<double> errors(factors.size());
  backend.linearize(factors, poses, lin);  // warm-up: uploads, batch layout
  Timing t;
  for (int r = 0; r < repeats; ++r) {
    Stopwatch w;
    backend.linearize(factors, poses, lin);
    t.linearize_ms += w.lap_ms();
    backend.trial_errors(factors, poses, errors);
    t.trial_ms += w.lap_ms();
  }
  t.linearize_ms /= repeats;
  t.trial_ms /= repeats;
  return t;
}

}  // namespace

int main() {
  std::string why;
  if (!cuda::device_available(&why)) {
    std::printf("skipped: no CUDA device (%s)\n", why.c_str());
    return 0;
  }
  const std::string dir = std::string(GCMAP_SHARED_DATA) + "/kitti07_submaps";
  if (!std::filesystem::exists(dir)) {
    std::printf("skipped: %s is absent\n", dir.c_str());
    return 0;
  }
  const Trajectory ref = read_trajectory(dir + "/graph.txt");
  std::vector<std::shared_ptr<const PointCloud>> clouds;
  std::vector<std::shared_ptr<const GaussianVoxelMap>> maps;
  size_t total_points = 0;
  for (int k = 0; k < 5; ++k) {
    PointCloud c = read_point_cloud(dir + "/00000" + std::to_string(k) + "/points.bin", BinFields::xyz);
    estimate_covariances(c);
    auto v = std::make_shared<GaussianVoxelMap>(1.0);
    v->insert(c);
    v->finalize();
    total_points += c.size();
    clouds.push_back(std::make_shared<const PointCloud>(std::move(c)));
    maps.push_back(v);
  }
  const size_t points_per_factor = total_points / 5;
  auto gpu = std::make_shared<cuda::CudaBackend>();
  std::printf("device: %s; %zu points per factor on average\n", gpu->device_name().c_str(), points_per_factor);

  for (int num_factors : {10, 100, 1000, 4500}) {
    // As bench_graph: variables cycle through the 5 clouds; every factor is a real overlapping pair.
    const int num_vars = std::max(5, num_factors / 5);
    Values values;
    for (int v = 0; v < num_vars; ++v) values[v] = ref.poses[v % 5];
    FactorGraph graph;
    for (int f = 0; graph.factors.size() < static_cast<size_t>(num_factors); ++f) {
      const int u = f % num_vars, step = 1 + (f / num_vars) % 4;
      const int v = (u + step) % num_vars;
      if (u % 5 == v % 5) continue;
      graph.add(std::make_shared<MatchingCostFactor>(u, v, clouds[u % 5], maps[v % 5]));
    }
    const double evaluations = static_cast<double>(num_factors) * points_per_factor;
    const Timing g = time_backend(*gpu, graph, values, 20);
    Timing c;
    {
      tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 2);
      CpuBackend cpu;
      c = time_backend(cpu, graph, values, num_factors >= 1000 ? 1 : 3);
    }
    std::printf("factors=%4d  GPU linearize %.2f ms (%.2f G point evaluations/s), trial %.2f ms | CPU 2 threads linearize %.1f ms, trial %.1f ms | speed-up %.0fx\n",
                num_factors, g.linearize_ms, evaluations / (g.linearize_ms / 1000.0) / 1e9, g.trial_ms, c.linearize_ms, c.trial_ms,
                c.linearize_ms / g.linearize_ms);
    // A full LM run on the GPU (5 iterations, no early stop).
    LMConfig config;
    config.max_iterations = 5;
    config.relative_error_tol = 0.0;
    config.step_tol = 0.0;
    Values vals = values;
    const LMResult r = LevenbergMarquardt(config, gpu).optimize(graph, vals, {0});
    std::printf("              LM on the GPU: %.2f ms/iteration (linearize+evaluate %.2f, solve %.2f)\n", r.total_ms / r.iterations,
                r.linearize_ms / r.iterations, r.solve_ms / r.iterations);
  }

  // Overlap of one source against many targets in one launch.
  for (int num_targets : {4, 100, 1000}) {
    std::vector<std::shared_ptr<const GaussianVoxelMap>> targets;
    std::vector<Eigen::Isometry3d> T;
    for (int k = 0; k < num_targets; ++k) {
      targets.push_back(maps[1 + k % 4]);
      T.push_back(ref.poses[1 + k % 4].inverse() * ref.poses[0]);
    }
    std::vector<double> out(num_targets);
    gpu->overlaps(clouds[0], targets, T, out);
    Stopwatch w;
    for (int r = 0; r < 20; ++r) gpu->overlaps(clouds[0], targets, T, out);
    const double ms = w.ms() / 20;
    std::printf("overlap: 1 source (%zu points) x %d targets: %.3f ms per launch, %.4f ms per pair\n", clouds[0]->size(), num_targets, ms,
                ms / num_targets);
  }
  const cuda::DeviceMemory m = gpu->memory();
  std::printf("device memory: %zu clouds, %zu points, %.1f bytes/point; %zu maps, %zu voxels in %zu slots, %.1f bytes/voxel (table included); batch buffers %.1f MB\n",
              m.num_clouds, m.num_points, static_cast<double>(m.cloud_bytes) / m.num_points, m.num_maps, m.num_voxels, m.num_slots,
              static_cast<double>(m.map_bytes) / m.num_voxels, m.batch_bytes / 1e6);
  return 0;
}
