// LM on graphs of 10, 100 and 1000 matching-cost factors over the real kitti07 clouds: linearization
// throughput and ms per iteration split into linearize / solve, for 1 and 2 threads. Not a test.
#include <tbb/global_control.h>

#include <cstdio>
#include <filesystem>

#include "gcmap/core/preprocess.hpp"
#include "gcmap/graph/levenberg_marquardt.hpp"
#include "gcmap/io/point_cloud_io.hpp"
#include "gcmap/io/trajectory_io.hpp"

using namespace gcmap;

int main() {
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
  for (int num_factors : {10, 100, 1000}) {
    // Variables cycle through the 5 clouds at their reference poses; each factor joins two variables
    // holding different clouds, so every factor is a real overlapping pair.
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
    for (int threads : {1, 2}) {
      tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
      LMConfig config;
      config.max_iterations = 5;
      config.relative_error_tol = 0.0;
      config.step_tol = 0.0;
      LevenbergMarquardt lm(config);
      Values vals = values;
      const LMResult r = lm.optimize(graph, vals, {0});
      size_t evaluations = 0;  // linearizations + trial evaluations, each touching every source point
      size_t trials = 0;
      for (const auto& it : r.history) trials += it.trials;
      const size_t points_per_factor = total_points / 5;
      evaluations = (r.iterations + 1 + trials) * num_factors * points_per_factor;
      std::printf("factors=%4d vars=%3d threads=%d  %.1f ms/iteration (linearize+evaluate %.1f, solve %.2f = %.1f%%)  %.1f M point evaluations/s\n",
                  num_factors, num_vars, threads, r.total_ms / r.iterations, r.linearize_ms / r.iterations,
                  r.solve_ms / r.iterations, 100.0 * r.solve_ms / r.total_ms, evaluations / (r.linearize_ms / 1000.0) / 1e6);
    }
  }
  return 0;
}
