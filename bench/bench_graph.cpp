// Graphs of 10, 100 and 1000 matching-cost factors over the real kitti07 clouds, 1 and 2 threads:
// throughput of the full linearization (transform, voxel lookup, fused covariance inverse,
// Jacobians, Hessian accumulation) and of LM's trial-step evaluation, each timed on its own, and
// LM ms per iteration split into linearize+evaluate / solve. Not a test.
#include <tbb/global_control.h>

#include <cstdio>

#include "gcmap/core/memory.hpp"
#include "gcmap/graph/levenberg_marquardt.hpp"
#include "kitti07_graph.hpp"

using namespace gcmap;

int main() {
  keep_large_buffers_in_heap();  // as gcmap does
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
    const double points = static_cast<double>(num_factors) * data->points_per_cloud;
    for (int threads : {1, 2}) {
      tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
      CpuBackend backend;
      const bench::Timing t = bench::time_backend(backend, graph, values, 3);
      LMConfig config;
      config.max_iterations = 5;
      config.relative_error_tol = 0.0;
      config.step_tol = 0.0;
      LevenbergMarquardt lm(config);
      Values vals = values;
      const LMResult r = lm.optimize(graph, vals, {0});
      int trials = 0;
      for (const LMIteration& it : r.history) trials += it.trials;
      std::printf("factors=%4d vars=%3d threads=%d  linearization %.1f M points/s (%.1f ms)  trial evaluation %.1f M points/s"
                  "  LM %.1f ms/iteration (%.1f trials; linearize+evaluate %.1f, solve %.2f = %.1f%%)\n",
                  num_factors, num_vars, threads, points / t.linearize_ms / 1e3, t.linearize_ms, points / t.trial_ms / 1e3,
                  r.total_ms / r.iterations, static_cast<double>(trials) / r.iterations, r.linearize_ms / r.iterations, r.solve_ms / r.iterations,
                  100.0 * r.solve_ms / r.total_ms);
    }
  }
  return 0;
}
