#pragma once
#include <atomic>
#include <functional>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "gcmap/graph/backend.hpp"
#include "gcmap/graph/sparse_solver.hpp"

namespace gcmap {

struct LMConfig {
  int max_iterations = 50;
  double initial_lambda = 1e-6;  // relative to diag(H) (Marquardt scaling)
  double max_lambda = 1e10;
  double lambda_up = 10.0;
  double relative_error_tol = 1e-6;  // stop when an accepted step lowers the error by less
  double step_tol = 1e-6;            // stop when the largest step component is smaller
  // A nearly undamped step that gained what its model predicted also stops, where its largest
  // component [rad, m] is at most this. A larger step moves points into other voxels, and the next
  // linearization finds more to gain: without the bound a matching-cost graph took one ICP-like
  // step per call, and a revisit crept over many insertions, each re-linearizing much of the graph.
  double predicted_stop_step = 0.01;
  LinearSolver linear_solver = LinearSolver::automatic;
};

struct LMIteration {
  int iteration = 0;
  double error = 0.0;  // after the accepted step, at its re-linearization (last iteration: its trial error)
  double lambda = 0.0;
  int trials = 0;
  double linearize_ms = 0.0;
  double assemble_ms = 0.0;  // H and b from the factors' blocks, and the damped copies
  double solve_ms = 0.0;     // factorizations, solves (the symbolic analysis runs beside the first linearization)
};

using IterationCallback = std::function<void(const LMIteration&)>;

struct LMResult {
  int iterations = 0;
  bool converged = false;
  double initial_error = 0.0;
  double final_error = 0.0;
  int analyses = 0;  // symbolic analyses run (0: the last call's pattern was reused)
  double linearize_ms = 0.0;
  double assemble_ms = 0.0;
  double solve_ms = 0.0;
  double total_ms = 0.0;
  std::vector<LMIteration> history;
};

// Levenberg-Marquardt over a block-sparse 6x6 system assembled from the factors' Hessian blocks,
// solved by a SparseSolver (Eigen or CHOLMOD, config.linear_solver) that keeps its symbolic analysis
// while the system's pattern stays the same, also across calls (a new pattern is analysed on a
// thread of its own while the first linearization runs); the damping lambda carries over
// between calls (warm start). Correspondence policy: each iteration re-linearizes (re-associates)
// every factor; trial steps are judged by Factor::trial_error with the association and robust
// weights of that linearization, so the gain ratio compares like with like, and a step is accepted
// only when that error decreases.
class LevenbergMarquardt {
 public:
  explicit LevenbergMarquardt(LMConfig config = {}, std::shared_ptr<LinearizationBackend> backend = nullptr);

  // Optimizes the non-fixed poses in place. Throws Error when a factor references a missing pose or
  // no factor touches a free pose (the system would be singular). A pose whose factors give no
  // information at the current estimate stays where it is.
  LMResult optimize(const FactorGraph& graph, Values& values, const std::set<int>& fixed = {});

  const LMConfig& config() const { return config_; }
  // Called after each iteration of optimize() (progress of a long optimization for a person).
  void on_iteration(IterationCallback callback) { on_iteration_ = std::move(callback); }
  // When *stop turns true, optimize() ends after the iteration under way, at its accepted poses (a
  // person's Ctrl-C must not wait for an optimization that runs for minutes).
  void stop_on(const std::atomic<bool>* stop) { stop_ = stop; }
  // The sparse solver in use (what linear_solver auto chose for the last system).
  LinearSolver active_solver() const { return solver_.active(); }

 private:
  class Iterations;
  struct Step {
    Values values;  // the poses after the step
    double error = 0.0, predicted = 0.0, lambda = 0.0, max_delta = 0.0;
  };
  // Raises the damping until a step lowers the error; nullopt when none does up to max_lambda.
  std::optional<Step> damped_step(Iterations& it, const Values& values, double error, LMIteration& stats);
  bool converged(double error, const Step& step) const;

  LMConfig config_;
  std::shared_ptr<LinearizationBackend> backend_;
  SparseSolver solver_;
  double lambda_;
  IterationCallback on_iteration_;
  const std::atomic<bool>* stop_ = nullptr;
};

}  // namespace gcmap
