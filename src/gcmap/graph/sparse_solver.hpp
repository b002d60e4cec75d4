#pragma once
// The sparse symmetric solve of one LM trial, (H + damping) x = rhs, with H given as its lower
// triangle. The symbolic analysis (fill-reducing ordering, elimination structure) depends only on
// the sparsity pattern: it is kept and redone only when the pattern changes.
#include <Eigen/SparseCore>
#include <memory>
#include <vector>

namespace gcmap {

// eigen: Eigen's simplicial LDL^T. cholmod: CHOLMOD's supernodal LL^T (SuiteSparse), in builds that
// found it; its speed is the system BLAS's. automatic ("auto", the default): eigen for systems with
// fewer than kAutoCholmodNonZeros stored non-zeros, cholmod from there on where the build has it;
// by size, not by timing, so that every run of a drive makes the same choice. The threshold is where
// bench_graph's factorization times cross (docs/pipeline.md).
enum class LinearSolver { eigen, cholmod, automatic };
const char* linear_solver_name(LinearSolver solver);
constexpr long kAutoCholmodNonZeros = 120000;
// Whether this build has CHOLMOD.
bool cholmod_available();

class SparseSolver {
 public:
  // Throws Error when cholmod is asked for in a build without it.
  explicit SparseSolver(LinearSolver kind = LinearSolver::eigen);
  ~SparseSolver();
  SparseSolver(SparseSolver&&) noexcept;
  SparseSolver& operator=(SparseSolver&&) noexcept;

  // Analyses A's pattern (lower triangle stored; its values are not read) unless it is the last
  // one analysed; an uncompressed A is always analysed. True when the analysis ran. LM calls it
  // ahead, beside its first linearization.
  bool analyse(const Eigen::SparseMatrix<double>& A);
  // Factorizes A, analysing first as analyse() does. False when A is not numerically
  // factorizable (e.g. not positive definite); the analysis is kept for the next try.
  bool factorize(const Eigen::SparseMatrix<double>& A);
  Eigen::VectorXd solve(const Eigen::VectorXd& rhs);

  LinearSolver kind() const { return kind_; }
  // The solver in use: kind(), or what automatic chose by the last analysed system.
  LinearSolver active() const { return active_; }
  // Analyses run, and factorizations that found theirs ready, since construction; ms per phase.
  int analyses() const { return analyses_; }
  int reuses() const { return reuses_; }
  double analyse_ms() const { return analyse_ms_; }
  double factorize_ms() const { return factorize_ms_; }
  double solve_ms() const { return solve_ms_; }

 private:
  struct Impl;
  void use_cholmod();
  LinearSolver kind_, active_;
  std::unique_ptr<Impl> impl_;
  std::vector<int> outer_, inner_;  // the analysed pattern
  int analyses_ = 0, reuses_ = 0;
  double analyse_ms_ = 0.0, factorize_ms_ = 0.0, solve_ms_ = 0.0;
};

}  // namespace gcmap
