#include "gcmap/graph/levenberg_marquardt.hpp"

#include <Eigen/SparseCore>
#include <algorithm>
#include <cmath>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

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
    for (int t = p.var_first[v]; t < p.var_first[v + 1]; ++t) sum += lin[p.var_terms[t] / 2].b.segment<6>(6 * (p.var_terms[t] % 2));
    b.segment<6>(6 * v) = sum;
  }
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

  Pattern pattern = make_pattern(s);
  const Eigen::SparseMatrix<double>& H = pattern.H;
  Eigen::SparseMatrix<double> A = H;  // the damped copy, same pattern
  Eigen::VectorXd b;
  const int analyses_before = solver_.analyses();

  for (int iter = 1; iter <= config_.max_iterations; ++iter) {
    LMIteration stats;
    stats.iteration = iter;
    const double lin_ms_before = result.linearize_ms;
    Stopwatch wa;
    assemble(lin, pattern, b);
    Eigen::VectorXd diag(6 * n);
    for (int k = 0; k < 6 * n; ++k) diag[k] = H.valuePtr()[H.outerIndexPtr()[k]];
    if (iter == 1) {
      for (int v = 0; v < n; ++v) {
        if (!(diag.segment<6>(6 * v).sum() > 0.0))
          throw Error("pose " + std::to_string(s.keys[v]) + " is not constrained by any factor (singular system)");
      }
    }
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
      std::copy(H.valuePtr(), H.valuePtr() + H.nonZeros(), A.valuePtr());
      for (int k = 0; k < 6 * n; ++k) A.valuePtr()[A.outerIndexPtr()[k]] += lambda_ * std::max(diag[k], 1e-6);
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
