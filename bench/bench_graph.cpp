// LM on graphs of 10, 100 and 1000 matching-cost factors over the real kitti07 clouds: linearization
// throughput and ms per iteration split into linearize / solve, for 1 and 2 threads. Not a test.
#include <tbb/global_control.h>

#include <cstdio>

#include "gcmap/graph/levenberg_marquardt.hpp"
#include "kitti07_graph.hpp"

using namespace gcmap;

int main() {
  const std::optional<bench::Kitti07> data = bench::Kitti07::load();
  if (!data) {
    std::printf("skipped: ../shared/data/kitti07_submaps is absent\n");
    return 0;
  }
  for (int num_factors : {10, 100, 1000}) {
    FactorGraph graph;
    Values values;
    data->make_graph(num_factors, graph, values);
    const int num_vars = static_cast<int>(values.size());
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
      const size_t points_per_factor = data->points_per_cloud;
      evaluations = (r.iterations + 1 + trials) * num_factors * points_per_factor;
      std::printf("factors=%4d vars=%3d threads=%d  %.1f ms/iteration (linearize+evaluate %.1f, solve %.2f = %.1f%%)  %.1f M point evaluations/s\n",
                  num_factors, num_vars, threads, r.total_ms / r.iterations, r.linearize_ms / r.iterations,
                  r.solve_ms / r.iterations, 100.0 * r.solve_ms / r.total_ms, evaluations / (r.linearize_ms / 1000.0) / 1e6);
    }
  }
  return 0;
}
