#include "gcmap/graph/levenberg_marquardt.hpp"

#include <Eigen/SparseCore>
#include <algorithm>
#include <cmath>

#include "gcmap/core/error.hpp"
#include "gcmap/core/timer.hpp"

namespace gcmap {

namespace {

// Block structure of the system for one optimize() call: variables, lower-triangle blocks and,
// per factor and key pair, which block receives the factor's Hessian block.
struct Structure {
  std::vector<int> keys;              // variable index -> key
  std::map<int, int> index;           // key -> variable index (free poses only)
  std::vector<std::pair<int, int>> blocks;  // (row, col), row >= col
  std::vector<std::array<int, 4>> factor_blocks;  // [a * 2 + c] -> block, -1 if absent
  std::vector<std::array<int, 2>> factor_vars;    // variable index per key, -1 if fixed/absent
};

Structure analyse(const FactorGraph& graph, const Values& values, const std::set<int>& fixed) {
  Structure s;
  for (const auto& [key, pose] : values) {
    if (fixed.count(key)) continue;
    s.index[key] = static_cast<int>(s.keys.size());
    s.keys.push_back(key);
  }
  std::map<std::pair<int, int>, int> block_index;
  auto block = [&](int r, int c) {
    const auto key = std::make_pair(std::max(r, c), std::min(r, c));
    auto it = block_index.find(key);
    if (it != block_index.end()) return it->second;
    const int id = static_cast<int>(s.blocks.size());
    s.blocks.push_back(key);
    block_index.emplace(key, id);
    return id;
  };
  for (size_t v = 0; v < s.keys.size(); ++v) block(static_cast<int>(v), static_cast<int>(v));
  for (const auto& f : graph.factors) {
    std::array<int, 2> vars{-1, -1};
    for (int k = 0; k < f->num_keys(); ++k) {
      const int key = f->keys()[k];
      if (!values.count(key)) throw Error("a factor references pose " + std::to_string(key) + ", which has no value");
      auto it = s.index.find(key);
      vars[k] = it == s.index.end() ? -1 : it->second;
    }
    std::array<int, 4> fb{-1, -1, -1, -1};
    for (int a = 0; a < f->num_keys(); ++a)
      for (int c = 0; c < f->num_keys(); ++c)
        if (vars[a] >= 0 && vars[c] >= 0 && vars[a] >= vars[c]) fb[a * 2 + c] = block(vars[a], vars[c]);
    s.factor_blocks.push_back(fb);
    s.factor_vars.push_back(vars);
  }
  return s;
}

// H (lower triangle) and b from the factors' linearizations. blocks and triplets are buffers.
void assemble(const Structure& s, std::span<Factor* const> factors, std::span<const FactorLinearization> lin,
              std::vector<Matrix6d>& blocks, std::vector<Eigen::Triplet<double>>& triplets, Eigen::SparseMatrix<double>& H,
              Eigen::VectorXd& b) {
  const int n = static_cast<int>(s.keys.size());
  for (auto& B : blocks) B.setZero();
  b.setZero(6 * n);
  for (size_t f = 0; f < factors.size(); ++f) {
    const int nk = factors[f]->num_keys();
    for (int a = 0; a < nk; ++a) {
      const int va = s.factor_vars[f][a];
      if (va < 0) continue;
      b.segment<6>(6 * va) += lin[f].b.segment<6>(6 * a);
      for (int c = 0; c < nk; ++c) {
        const int blk = s.factor_blocks[f][a * 2 + c];
        if (blk >= 0) blocks[blk] += lin[f].H.block<6, 6>(6 * a, 6 * c);
      }
    }
  }
  triplets.clear();
  for (size_t k = 0; k < s.blocks.size(); ++k) {
    const auto [r, c] = s.blocks[k];
    for (int i = 0; i < 6; ++i)
      for (int j = 0; j < 6; ++j)
        if (r != c || i >= j) triplets.emplace_back(6 * r + i, 6 * c + j, blocks[k](i, j));
  }
  H.resize(6 * n, 6 * n);
  H.setFromTriplets(triplets.begin(), triplets.end());
}

}  // namespace

LevenbergMarquardt::LevenbergMarquardt(LMConfig config, std::shared_ptr<LinearizationBackend> backend)
    : config_(config), backend_(backend ? std::move(backend) : std::make_shared<CpuBackend>()),
      solver_(config.linear_solver), lambda_(config.initial_lambda) {}

LMResult LevenbergMarquardt::optimize(const FactorGraph& graph, Values& values, const std::set<int>& fixed) {
  Stopwatch total;
  LMResult result;
  const Structure s = analyse(graph, values, fixed);
  const size_t nf = graph.factors.size();
  const int n = static_cast<int>(s.keys.size());
  std::vector<Factor*> factors(nf);
  for (size_t f = 0; f < nf; ++f) factors[f] = graph.factors[f].get();

  auto factor_poses = [&](const Values& vals) {
    std::vector<FactorPoses> poses(nf);
    for (size_t f = 0; f < nf; ++f)
      for (int k = 0; k < factors[f]->num_keys(); ++k) poses[f][k] = &vals.at(factors[f]->keys()[k]);
    return poses;
  };

  std::vector<FactorLinearization> lin(nf);
  std::vector<double> trial(nf);
  auto linearize = [&](const Values& vals) {
    Stopwatch w;
    const auto poses = factor_poses(vals);
    backend_->linearize(factors, poses, lin);
    double e = 0.0;
    for (const auto& l : lin) e += l.error;
    result.linearize_ms += w.ms();
    return e;
  };

  double error = linearize(values);
  result.initial_error = result.final_error = error;
  if (n == 0 || nf == 0) {
    result.converged = true;
    result.total_ms = total.ms();
    return result;
  }

  std::vector<Matrix6d> blocks(s.blocks.size());
  std::vector<Eigen::Triplet<double>> triplets;
  triplets.reserve(s.blocks.size() * 36);
  Eigen::SparseMatrix<double> H;
  Eigen::VectorXd b;
  const int analyses_before = solver_.analyses();

  for (int iter = 1; iter <= config_.max_iterations; ++iter) {
    LMIteration stats;
    stats.iteration = iter;
    const double lin_ms_before = result.linearize_ms;
    Stopwatch wa;
    assemble(s, factors, lin, blocks, triplets, H, b);
    if (iter == 1) {
      for (int v = 0; v < n; ++v) {
        if (!(blocks[v].trace() > 0.0))
          throw Error("pose " + std::to_string(s.keys[v]) + " is not constrained by any factor (singular system)");
      }
    }
    const Eigen::VectorXd diag = H.diagonal();
    stats.assemble_ms = wa.ms();
    // H is stored as its lower triangle: H * x needs the symmetric view.
    auto quad = [&](const Eigen::VectorXd& x) { return x.dot(H.selfadjointView<Eigen::Lower>() * x); };

    bool accepted = false;
    Values trial_values;
    double trial_error = 0.0, predicted_decrease = 0.0, step_lambda = 0.0;
    Eigen::VectorXd delta;
    stats.solve_ms = 0.0;
    while (lambda_ <= config_.max_lambda) {
      ++stats.trials;
      Stopwatch wa_trial;
      Eigen::SparseMatrix<double> A = H;
      for (int k = 0; k < 6 * n; ++k) A.coeffRef(k, k) += lambda_ * std::max(diag[k], 1e-6);
      stats.assemble_ms += wa_trial.ms();
      Stopwatch w;
      const bool factorized = solver_.factorize(A);
      if (factorized) delta = solver_.solve(-b);
      stats.solve_ms += w.ms();
      if (!factorized || !delta.allFinite()) {
        lambda_ *= config_.lambda_up;
        continue;
      }
      trial_values = values;
      for (int v = 0; v < n; ++v) {
        Eigen::Isometry3d& T = trial_values.at(s.keys[v]);
        T = normalized(T * se3_exp(delta.segment<6>(6 * v)));
      }
      {
        Stopwatch wl;
        const auto poses = factor_poses(trial_values);
        backend_->trial_errors(factors, poses, trial);
        result.linearize_ms += wl.ms();
      }
      trial_error = 0.0;
      for (double e : trial) trial_error += e;
      const double predicted = -(2.0 * b.dot(delta) + quad(delta));
      if (std::isfinite(trial_error) && trial_error < error) {
        const double rho = predicted > 0 ? (error - trial_error) / predicted : 0.5;
        predicted_decrease = predicted;
        step_lambda = lambda_;
        lambda_ = std::max(lambda_ * std::max(1.0 / 3.0, 1.0 - std::pow(2.0 * rho - 1.0, 3)), 1e-12);
        accepted = true;
        break;
      }
      lambda_ *= config_.lambda_up;
    }
    result.solve_ms += stats.solve_ms;
    result.assemble_ms += stats.assemble_ms;
    stats.lambda = lambda_;
    if (!accepted) {
      // No damping gives a decrease: a minimum of the current linearization.
      lambda_ = config_.initial_lambda;
      result.converged = true;
      stats.error = error;
      stats.linearize_ms = result.linearize_ms - lin_ms_before;
      result.history.push_back(stats);
      result.iterations = iter;
      break;
    }
    const double decrease = error - trial_error;
    values = std::move(trial_values);
    // Converged also when a nearly undamped step gained what the quadratic model predicted to within
    // the tolerance: the next step would gain about that model error, so it is not worth its
    // linearization (mostly the confirming second iteration of a warm-started insertion).
    const double tol = config_.relative_error_tol * std::max(trial_error, 1e-12);
    result.converged = decrease < tol || delta.lpNorm<Eigen::Infinity>() < config_.step_tol ||
                       (step_lambda <= 1e-3 && std::abs(decrease - predicted_decrease) < tol);
    // A linearization nobody will use is the most expensive thing LM could do here: the last
    // iteration reports its trial error (same association) instead.
    const bool last = result.converged || iter == config_.max_iterations;
    error = last ? trial_error : linearize(values);
    stats.error = error;
    stats.linearize_ms = result.linearize_ms - lin_ms_before;
    result.history.push_back(stats);
    result.iterations = iter;
    if (last) break;
  }
  result.final_error = error;
  result.analyses = solver_.analyses() - analyses_before;
  result.total_ms = total.ms();
  return result;
}

}  // namespace gcmap
