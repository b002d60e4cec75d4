// 1. The sparse solve alone, on synthetic mapping-shaped systems of 100 to 1,000 poses and on the
//    factor pattern of each `gcmap map` graph.json given as an argument: symbolic analysis, numeric
//    factorization and solve, Eigen's simplicial LDL^T against CHOLMOD's supernodal LL^T
//    (graph/sparse_solver.hpp). Needs no data.
// 2. Graphs of 10 to 4,500 matching-cost factors over the real kitti07 clouds, 1 and 2 threads:
//    throughput of the full linearization (transform, voxel lookup, fused covariance inverse,
//    Jacobians, Hessian accumulation) and of LM's trial-step evaluation, each timed on its own, also
//    with a copy of the clouds per variable (from 1,000 factors: out of the caches, as in a mapping
//    run), and LM ms per iteration split into linearize+evaluate / assemble / solve per linear solver.
// Not a test.
#include <tbb/global_control.h>

#include <algorithm>
#include <cstdio>
#include <random>
#include <span>

#include "gcmap/core/memory.hpp"
#include "gcmap/graph/levenberg_marquardt.hpp"
#include "gcmap/viz/run_data.hpp"
#include "kitti07_graph.hpp"

using namespace gcmap;

namespace {

// Block pairs of a synthetic mapping graph: each submap overlapping its `sequential` predecessors,
// and a route that comes back every `lap` submaps, where each submap also overlaps three submaps
// around the same place on each of the last `laps_back` laps.
std::vector<std::pair<int, int>> mapping_pairs(int poses, int sequential, int lap, int laps_back) {
  std::vector<std::pair<int, int>> pairs;
  for (int i = 1; i < poses; ++i) {
    for (int k = 1; k <= sequential && i - k >= 0; ++k) pairs.emplace_back(i, i - k);
    for (int back = lap; i - back - 1 >= 0 && back <= laps_back * lap; back += lap)
      for (int d = -1; d <= 1; ++d)
        if (i - back + d >= 0 && i - back + d < i - sequential) pairs.emplace_back(i, i - back + d);
  }
  return pairs;
}

// Lower triangle of the damped 6n x 6n system of those pairs with pose 0 fixed (left out): each
// factor adds a random positive semi-definite 12x12 block, as J^T J does.
Eigen::SparseMatrix<double> mapping_system(int poses, const std::vector<std::pair<int, int>>& pairs) {
  std::mt19937 rng(7);
  std::normal_distribution<double> normal;
  std::vector<Eigen::Triplet<double>> triplets;
  const int n = poses - 1;
  auto add = [&](int r, int c, double v) {
    if (r >= 6 && c >= 6) triplets.emplace_back(std::max(r, c) - 6, std::min(r, c) - 6, v);
  };
  for (const auto& [i, j] : pairs) {
    Eigen::Matrix<double, 12, 12> G;
    for (int r = 0; r < 12; ++r)
      for (int c = 0; c < 12; ++c) G(r, c) = normal(rng);
    const Eigen::Matrix<double, 12, 12> M = G.transpose() * G;
    const int base[2] = {6 * i, 6 * j};
    for (int a = 0; a < 2; ++a)
      for (int c = 0; c < 2; ++c)
        for (int r = 0; r < 6; ++r)
          for (int q = 0; q < 6; ++q)
            if (base[a] + r >= base[c] + q) add(base[a] + r, base[c] + q, M(6 * a + r, 6 * c + q));
  }
  Eigen::SparseMatrix<double> A(6 * n, 6 * n);
  A.setFromTriplets(triplets.begin(), triplets.end());
  for (int k = 0; k < 6 * n; ++k) A.coeffRef(k, k) += 1e-3;
  return A;
}

struct SolveTiming {
  double analyse_ms = 1e300, factorize_ms = 1e300, solve_ms = 1e300, residual = 0.0;
};

// Minimum over `repeats` of each phase (the VM is shared: the minimum is the least disturbed run).
// A fresh solver's first factorization times the analysis; the second one reuses it.
SolveTiming time_solver(LinearSolver kind, const Eigen::SparseMatrix<double>& A, int repeats) {
  SolveTiming t;
  const Eigen::VectorXd rhs = Eigen::VectorXd::Ones(A.rows());
  Eigen::VectorXd x;
  for (int r = 0; r < repeats; ++r) {
    SparseSolver solver(kind);
    solver.factorize(A);
    t.analyse_ms = std::min(t.analyse_ms, solver.analyse_ms());
    const double first = solver.factorize_ms();
    solver.factorize(A);
    t.factorize_ms = std::min(t.factorize_ms, solver.factorize_ms() - first);
    x = solver.solve(rhs);
    t.solve_ms = std::min(t.solve_ms, solver.solve_ms());
  }
  t.residual = (A.selfadjointView<Eigen::Lower>() * x - rhs).norm() / rhs.norm();
  return t;
}

void print_solvers(const char* label, int poses, size_t factors, const Eigen::SparseMatrix<double>& A) {
  const int repeats = poses >= 500 ? 7 : 20;
  const SolveTiming e = time_solver(LinearSolver::eigen, A, repeats);
  std::printf("%-16s %6d %7zu %9ld | %8.2f %8.2f %8.3f    |", label, poses, factors, static_cast<long>(A.nonZeros()),
              e.analyse_ms, e.factorize_ms, e.solve_ms);
  if (!cholmod_available()) {
    std::printf(" (built without CHOLMOD)\n");
    return;
  }
  const SolveTiming c = time_solver(LinearSolver::cholmod, A, repeats);
  std::printf(" %8.2f %8.2f %8.3f    | %.2f / %.2f / %.2f  (residuals %.0e, %.0e)\n", c.analyse_ms, c.factorize_ms, c.solve_ms,
              c.analyse_ms / e.analyse_ms, c.factorize_ms / e.factorize_ms, c.solve_ms / e.solve_ms, e.residual, c.residual);
}

// Synthetic graphs (4 sequential overlaps, a route repeating every 100 submaps), then the factor
// pattern of each graph.json given (a `gcmap map` output) with random blocks.
void bench_solvers(std::span<char*> graph_jsons) {
  std::printf("sparse solve, ms; synthetic: 4 sequential overlaps, route repeating every 100 submaps\n");
  std::printf("%-16s %6s %7s %9s | %-28s | %-28s | cholmod/eigen\n", "graph", "poses", "factors", "nnz(H)",
              "eigen analyse/factor/solve", "cholmod analyse/factor/solve");
  for (int laps_back : {1, 1000}) {
    for (int poses : {100, 300, 1000}) {
      const auto pairs = mapping_pairs(poses, 4, 100, laps_back);
      print_solvers(laps_back == 1 ? "synthetic, 1 lap" : "synthetic, all", poses, pairs.size(), mapping_system(poses, pairs));
    }
  }
  for (int factors : {1000, 4500}) {
    const auto pairs = bench::Kitti07::graph_pairs(factors);
    print_solvers("kitti07 bench", std::max(5, factors / 5), pairs.size(), mapping_system(std::max(5, factors / 5), pairs));
  }
  for (const char* path : graph_jsons) {
    const viz::RunGraph run = viz::read_graph_json(path);
    std::vector<std::pair<int, int>> pairs;
    for (const viz::GraphEdge& e : run.edges) pairs.emplace_back(e.source, e.target);
    const int poses = static_cast<int>(run.nodes.size());
    print_solvers(std::filesystem::path(path).parent_path().filename().c_str(), poses, pairs.size(),
                  mapping_system(poses, pairs));
  }
}

// The same graph with a copy of the clouds and voxel maps per variable: a mapping run's graph has a
// map per submap, far more than the caches hold, so each factor reads its target from memory.
void print_distinct(const bench::Kitti07& data, int num_factors, double points, double shared_ms) {
  FactorGraph graph;
  Values values;
  data.make_graph(num_factors, graph, values, true);
  CpuBackend backend;
  const bench::Timing t = bench::time_backend(backend, graph, values, 1);
  std::printf(
      "  a copy of the clouds per variable: linearization %.1f M points/s (%.1f ms, %.2fx the shared clouds'"
      " time)  trial evaluation %.1f M points/s\n",
      points / t.linearize_ms / 1e3, t.linearize_ms, t.linearize_ms / shared_ms, points / t.trial_ms / 1e3);
}

// Trial errors with the voxels kept from the linearization (TrialVoxels::kept, as in-submap factors
// have them) against looking them up again.
void print_kept(const bench::Kitti07& data, int num_factors, double points, double looked_up_ms) {
  FactorGraph graph;
  Values values;
  data.make_graph(num_factors, graph, values, false, TrialVoxels::kept);
  CpuBackend backend;
  const bench::Timing t = bench::time_backend(backend, graph, values, num_factors >= 1000 ? 1 : 3);
  std::printf("  voxels kept from the linearization: trial evaluation %.1f M points/s (%.2fx the time of looking them up)\n",
              points / t.trial_ms / 1e3, t.trial_ms / looked_up_ms);
}

void bench_lm(const bench::Kitti07& data) {
  for (int num_factors : {10, 100, 1000, 4500}) {
    FactorGraph graph;
    Values values;
    data.make_graph(num_factors, graph, values);
    const int num_vars = static_cast<int>(values.size());
    const double points = static_cast<double>(num_factors) * data.points_per_cloud;
    for (int threads : {1, 2}) {
      tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
      CpuBackend backend;
      const bench::Timing t = bench::time_backend(backend, graph, values, num_factors >= 1000 ? 1 : 3);
      std::printf("factors=%4d vars=%3d threads=%d  linearization %.1f M points/s (%.1f ms)  trial evaluation %.1f M points/s\n",
                  num_factors, num_vars, threads, points / t.linearize_ms / 1e3, t.linearize_ms, points / t.trial_ms / 1e3);
      if (num_factors <= 1000) print_kept(data, num_factors, points, t.trial_ms);
      if (num_factors >= 1000) print_distinct(data, num_factors, points, t.linearize_ms);
      if (threads == 1) continue;
      for (LinearSolver kind : {LinearSolver::eigen, LinearSolver::cholmod}) {
        if (kind == LinearSolver::cholmod && !cholmod_available()) continue;
        LMConfig config;
        config.max_iterations = num_factors >= 1000 ? 3 : 5;
        config.relative_error_tol = 0.0;
        config.step_tol = 0.0;
        config.linear_solver = kind;
        LevenbergMarquardt lm(config);
        Values vals = values;
        const LMResult r = lm.optimize(graph, vals, {0});
        int trials = 0;
        for (const LMIteration& it : r.history) trials += it.trials;
        const double per = 1.0 / r.iterations;
        std::printf("  LM %-7s %.1f ms/iteration (%.1f trials): linearize+evaluate %.1f, assemble %.2f, solve %.2f (%.1f%%)\n",
                    linear_solver_name(kind), r.total_ms * per, trials * per, r.linearize_ms * per, r.assemble_ms * per,
                    r.solve_ms * per, 100.0 * r.solve_ms / r.total_ms);
      }
    }
  }
}

}  // namespace

int main(int argc, char** argv) {
  keep_large_buffers_in_heap();  // as gcmap does
  bench_solvers(std::span<char*>(argv + 1, argc - 1));
  const std::optional<bench::Kitti07> data = bench::Kitti07::load();
  if (!data) {
    std::printf("LM on kitti07 graphs skipped: ../shared/data/kitti07_submaps is absent\n");
    return 0;
  }
  bench_lm(*data);
  return 0;
}
