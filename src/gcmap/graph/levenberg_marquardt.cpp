#include "gcmap/graph/levenberg_marquardt.hpp"

#include <Eigen/SparseCore>
#include <algorithm>
#include <cmath>
#include <future>
#include <optional>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "gcmap/core/error.hpp"
#include "gcmap/core/timer.hpp"

namespace gcmap {

namespace {

// Block structure of the system for one optimize() call: variables, lower-triangle blocks and,
// per factor and key pair, which block receives the factor's Hessian block.
struct Structure {
  std::vector<int> keys;                          // variable index -> key
  std::map<int, int> index;                       // key -> variable index (free poses only)
  std::vector<std::pair<int, int>> blocks;        // (row, col), row >= col
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

// The compressed lower triangle of H for one optimize() call, built once: assembling an iteration
// writes the factors' blocks straight into its values (no triplets, no sorting), block by block in
// parallel, and a damped trial copies the values and adds to the diagonal, which leads every column.
struct Pattern {
  Eigen::SparseMatrix<double> H;
  std::vector<std::array<int, 6>> block_column_start;  // per block and column j: value index of its first row
  std::vector<bool> block_is_diagonal;
  // What each block and each variable's b receive: factor * 4 + a * 2 + c (H block (a, c) of the
  // factor), factor * 2 + a (b segment a), in CSR layout.
  std::vector<int> block_first, block_terms, var_first, var_terms;
};

// Groups (owner, term) pairs by owner in CSR layout.
void to_csr(std::vector<std::pair<int, int>>& pairs, int owners, std::vector<int>& first, std::vector<int>& terms) {
  std::stable_sort(pairs.begin(), pairs.end(), [](const auto& x, const auto& y) { return x.first < y.first; });
  first.assign(owners + 1, 0);
  for (const auto& [owner, term] : pairs) ++first[owner + 1];
  for (int o = 0; o < owners; ++o) first[o + 1] += first[o];
  terms.resize(pairs.size());
  for (size_t i = 0; i < pairs.size(); ++i) terms[i] = pairs[i].second;
}

Pattern make_pattern(const Structure& s) {
  const int n = static_cast<int>(s.keys.size());
  std::vector<std::vector<int>> blocks_of_column(n);  // block ids by column, rows ascending
  for (size_t k = 0; k < s.blocks.size(); ++k) blocks_of_column[s.blocks[k].second].push_back(static_cast<int>(k));
  for (auto& col : blocks_of_column)
    std::sort(col.begin(), col.end(), [&](int a, int b) { return s.blocks[a].first < s.blocks[b].first; });
  Pattern p;
  p.block_column_start.resize(s.blocks.size());
  p.block_is_diagonal.resize(s.blocks.size());
  std::vector<int> outer(6 * n + 1, 0), inner;
  for (int c = 0; c < n; ++c) {
    for (int j = 0; j < 6; ++j) {
      for (const int k : blocks_of_column[c]) {
        const int r = s.blocks[k].first;
        const bool diagonal = r == c;
        p.block_is_diagonal[k] = diagonal;
        p.block_column_start[k][j] = static_cast<int>(inner.size());
        for (int i = diagonal ? j : 0; i < 6; ++i) inner.push_back(6 * r + i);
      }
      outer[6 * c + j + 1] = static_cast<int>(inner.size());
    }
  }
  p.H.resize(6 * n, 6 * n);
  p.H.resizeNonZeros(static_cast<Eigen::Index>(inner.size()));
  std::copy(outer.begin(), outer.end(), p.H.outerIndexPtr());
  std::copy(inner.begin(), inner.end(), p.H.innerIndexPtr());

  std::vector<std::pair<int, int>> block_terms, var_terms;
  for (size_t f = 0; f < s.factor_vars.size(); ++f) {
    const int fi = static_cast<int>(f);
    for (int a = 0; a < 2; ++a) {
      if (s.factor_vars[f][a] >= 0) var_terms.emplace_back(s.factor_vars[f][a], fi * 2 + a);
      for (int c = 0; c < 2; ++c)
        if (s.factor_blocks[f][a * 2 + c] >= 0) block_terms.emplace_back(s.factor_blocks[f][a * 2 + c], fi * 4 + a * 2 + c);
    }
  }
  to_csr(block_terms, static_cast<int>(s.blocks.size()), p.block_first, p.block_terms);
  to_csr(var_terms, n, p.var_first, p.var_terms);
  return p;
}

// H (lower triangle, into p.H's values) and b from the factors' linearizations.
void assemble(std::span<const FactorLinearization> lin, Pattern& p, Eigen::VectorXd& b) {
  double* values = p.H.valuePtr();
  const int num_blocks = static_cast<int>(p.block_is_diagonal.size());
  tbb::parallel_for(tbb::blocked_range<int>(0, num_blocks, 64), [&](const tbb::blocked_range<int>& r) {
    for (int blk = r.begin(); blk != r.end(); ++blk) {
      Matrix6d sum = Matrix6d::Zero();
      for (int t = p.block_first[blk]; t < p.block_first[blk + 1]; ++t) {
        const int term = p.block_terms[t], f = term / 4, a = (term / 2) % 2, c = term % 2;
        sum += lin[f].H.block<6, 6>(6 * a, 6 * c);
      }
      const int first = p.block_is_diagonal[blk] ? 1 : 0;
      for (int j = 0; j < 6; ++j) {
        double* column = values + p.block_column_start[blk][j] - first * j;
        for (int i = first * j; i < 6; ++i) column[i] = sum(i, j);
      }
    }
  });
  const int n = static_cast<int>(p.var_first.size()) - 1;
  b.resize(6 * n);
  for (int v = 0; v < n; ++v) {
    Vector6d sum = Vector6d::Zero();
    for (int t = p.var_first[v]; t < p.var_first[v + 1]; ++t)
      sum += lin[p.var_terms[t] / 2].b.segment<6>(6 * (p.var_terms[t] % 2));
    b.segment<6>(6 * v) = sum;
  }
}

}  // namespace

// One optimize() call's state: the factors, their linearizations and the system's pattern. The
// damping and the solver belong to the LevenbergMarquardt object (they carry over between calls).
class LevenbergMarquardt::Iterations {
 public:
  Iterations(const FactorGraph& graph, const Values& values, const std::set<int>& fixed, LinearizationBackend& backend,
             LMResult& result)
      : s_(analyse(graph, values, fixed)), backend_(backend), result_(result) {
    for (const auto& f : graph.factors) factors_.push_back(f.get());
    lin_.resize(factors_.size());
    trial_.resize(factors_.size());
  }
  ~Iterations() {
    for (Factor* f : factors_) f->release_trial_state();
  }
  Iterations(const Iterations&) = delete;
  Iterations& operator=(const Iterations&) = delete;

  int num_vars() const { return static_cast<int>(s_.keys.size()); }
  bool empty() const { return s_.keys.empty() || factors_.empty(); }

  // Linearizes every factor at `values`; returns the total error.
  double linearize(const Values& values) {
    Stopwatch w;
    backend_.linearize(factors_, factor_poses(values), lin_);
    double e = 0.0;
    for (const auto& l : lin_) e += l.error;
    result_.linearize_ms += w.ms();
    return e;
  }

  // The system's pattern and its symbolic analysis: they need no linearization, so optimize() runs
  // this beside the first one (on the GPU backend the host would otherwise wait for the device).
  void prepare(SparseSolver& solver) {
    pattern_ = make_pattern(s_);
    A_ = pattern_->H;
    solver.analyse(A_);
  }

  // H and b from the current linearizations, and H's diagonal (the damping's scale).
  void assemble(bool first) {
    gcmap::assemble(lin_, *pattern_, b_);
    const Eigen::SparseMatrix<double>& H = pattern_->H;
    diag_.resize(6 * num_vars());
    for (int k = 0; k < 6 * num_vars(); ++k) diag_[k] = H.valuePtr()[H.outerIndexPtr()[k]];
    if (!first) return;
    for (int v = 0; v < num_vars(); ++v)
      if (pattern_->var_first[v + 1] == pattern_->var_first[v])
        throw Error("pose " + std::to_string(s_.keys[v]) + " is not constrained by any factor (singular system)");
  }

  // Solves (H + lambda diag(H)) delta = -b; false when that system cannot be factorized.
  bool solve(SparseSolver& solver, double lambda, Eigen::VectorXd& delta, LMIteration& stats) {
    Stopwatch wa;
    const Eigen::SparseMatrix<double>& H = pattern_->H;
    std::copy(H.valuePtr(), H.valuePtr() + H.nonZeros(), A_.valuePtr());
    // A pose whose factors give no information here (a loop's kernel at zero weight, a matching
    // cost without correspondences) has a zero row in H: a unit diagonal keeps it where it is.
    for (int k = 0; k < 6 * num_vars(); ++k)
      A_.valuePtr()[A_.outerIndexPtr()[k]] += diag_[k] > 0.0 ? lambda * std::max(diag_[k], 1e-6) : 1.0;
    stats.assemble_ms += wa.ms();
    Stopwatch w;
    const bool factorized = solver.factorize(A_);
    if (factorized) delta = solver.solve(-b_);
    stats.solve_ms += w.ms();
    return factorized && delta.allFinite();
  }

  // The poses moved by delta, and their error with the current linearizations' associations.
  double trial(const Values& values, const Eigen::VectorXd& delta, Values& moved) {
    moved = values;
    for (int v = 0; v < num_vars(); ++v) {
      Eigen::Isometry3d& T = moved.at(s_.keys[v]);
      T = normalized(T * se3_exp(delta.segment<6>(6 * v)));
    }
    Stopwatch w;
    backend_.trial_errors(factors_, factor_poses(moved), trial_);
    result_.linearize_ms += w.ms();
    double e = 0.0;
    for (double t : trial_) e += t;
    return e;
  }

  // The decrease of the error that the quadratic model predicts for delta.
  double predicted_decrease(const Eigen::VectorXd& delta) const {
    // H is stored as its lower triangle: H * x needs the symmetric view.
    return -(2.0 * b_.dot(delta) + delta.dot(pattern_->H.selfadjointView<Eigen::Lower>() * delta));
  }

 private:
  std::vector<FactorPoses> factor_poses(const Values& values) const {
    std::vector<FactorPoses> poses(factors_.size());
    for (size_t f = 0; f < factors_.size(); ++f)
      for (int k = 0; k < factors_[f]->num_keys(); ++k) poses[f][k] = &values.at(factors_[f]->keys()[k]);
    return poses;
  }

  const Structure s_;
  LinearizationBackend& backend_;
  LMResult& result_;
  std::vector<Factor*> factors_;
  std::vector<FactorLinearization> lin_;
  std::vector<double> trial_;
  std::optional<Pattern> pattern_;
  Eigen::SparseMatrix<double> A_;  // the damped copy of H, same pattern
  Eigen::VectorXd b_, diag_;
};

LevenbergMarquardt::LevenbergMarquardt(LMConfig config, std::shared_ptr<LinearizationBackend> backend)
    : config_(config),
      backend_(backend ? std::move(backend) : std::make_shared<CpuBackend>()),
      solver_(config.linear_solver),
      lambda_(config.initial_lambda) {}

std::optional<LevenbergMarquardt::Step> LevenbergMarquardt::damped_step(Iterations& it, const Values& values, double error,
                                                                        LMIteration& stats) {
  Step step;
  Eigen::VectorXd delta;
  for (; lambda_ <= config_.max_lambda; lambda_ *= config_.lambda_up) {
    ++stats.trials;
    if (!it.solve(solver_, lambda_, delta, stats)) continue;
    step.error = it.trial(values, delta, step.values);
    if (!(std::isfinite(step.error) && step.error < error)) continue;
    step.predicted = it.predicted_decrease(delta);
    step.lambda = lambda_;
    step.max_delta = delta.lpNorm<Eigen::Infinity>();
    const double rho = step.predicted > 0 ? (error - step.error) / step.predicted : 0.5;
    lambda_ = std::max(lambda_ * std::max(1.0 / 3.0, 1.0 - std::pow(2.0 * rho - 1.0, 3)), 1e-12);
    return step;
  }
  return std::nullopt;
}

bool LevenbergMarquardt::converged(double error, const Step& step) const {
  const double decrease = error - step.error;
  // Converged also when a small, nearly undamped step gained what the quadratic model predicted to
  // within the tolerance: the next step would gain about that model error, so it is not worth its
  // linearization (mostly the confirming second iteration of a warm-started insertion).
  const double tol = config_.relative_error_tol * std::max(step.error, 1e-12);
  return decrease < tol || step.max_delta < config_.step_tol ||
         (step.lambda <= 1e-3 && step.max_delta <= config_.predicted_stop_step && std::abs(decrease - step.predicted) < tol);
}

LMResult LevenbergMarquardt::optimize(const FactorGraph& graph, Values& values, const std::set<int>& fixed) {
  Stopwatch total;
  LMResult result;
  Iterations it(graph, values, fixed, *backend_, result);
  const int analyses_before = solver_.analyses();
  std::future<void> prepared;
  if (!it.empty()) prepared = std::async(std::launch::async, [&] { it.prepare(solver_); });
  double error = it.linearize(values);
  if (prepared.valid()) prepared.get();
  result.initial_error = result.final_error = error;
  if (it.empty()) {
    result.converged = true;
    result.total_ms = total.ms();
    return result;
  }
  for (int iter = 1; iter <= config_.max_iterations; ++iter) {
    if (iter > 1 && stop_ && stop_->load()) break;
    LMIteration stats;
    stats.iteration = iter;
    const double lin_ms_before = result.linearize_ms;
    Stopwatch wa;
    it.assemble(iter == 1);
    stats.assemble_ms = wa.ms();
    std::optional<Step> step = damped_step(it, values, error, stats);
    result.solve_ms += stats.solve_ms;
    result.assemble_ms += stats.assemble_ms;
    stats.lambda = lambda_;
    result.iterations = iter;
    // No step: no damping gives a decrease, a minimum of the current linearization.
    if (!step) lambda_ = config_.initial_lambda;
    result.converged = !step || converged(error, *step);
    // A linearization nobody will use is the most expensive thing LM could do here: the last
    // iteration reports its trial error (same association) instead.
    const bool last = result.converged || iter == config_.max_iterations || (stop_ && stop_->load());
    if (step) {
      values = std::move(step->values);
      error = last ? step->error : it.linearize(values);
    }
    stats.error = error;
    stats.linearize_ms = result.linearize_ms - lin_ms_before;
    result.history.push_back(stats);
    if (on_iteration_) on_iteration_(stats);
    if (last) break;
  }
  result.final_error = error;
  result.analyses = solver_.analyses() - analyses_before;
  result.total_ms = total.ms();
  return result;
}

}  // namespace gcmap
