#pragma once
// The sparse symmetric solve of one LM trial, (H + damping) x = rhs, with H given as its lower
// triangle. The symbolic analysis (fill-reducing ordering, elimination structure) depends only on
// the sparsity pattern: it is kept and redone only when the pattern changes.
#include <Eigen/SparseCore>
#include <memory>
#include <vector>

namespace gcmap {

// eigen: Eigen's simplicial LDL^T. cholmod: CHOLMOD's supernodal LL^T (SuiteSparse), in builds that
// found it; its speed is the system BLAS's: with OpenBLAS 3.7-8.5x faster than eigen at 1,000
// submaps, on par at 300 and below; with the reference BLAS slower but on dense revisited graphs
// (bench_graph).
enum class LinearSolver { eigen, cholmod };
const char* linear_solver_name(LinearSolver solver);
// Whether this build has CHOLMOD.
bool cholmod_available();

class SparseSolver {
 public:
  // Throws Error when cholmod is asked for in a build without it.
  explicit SparseSolver(LinearSolver kind = LinearSolver::eigen);
  ~SparseSolver();
  SparseSolver(SparseSolver&&) noexcept;
  SparseSolver& operator=(SparseSolver&&) noexcept;

  // Factorizes A (lower triangle stored), analysing first when its pattern differs from the last
  // analysed one (an uncompressed A is always analysed). False when A is not numerically
  // factorizable (e.g. not positive definite); the analysis is kept for the next try.
  bool factorize(const Eigen::SparseMatrix<double>& A);
  Eigen::VectorXd solve(const Eigen::VectorXd& rhs);

  LinearSolver kind() const { return kind_; }
  // Analyses run and reused since construction; ms spent in each phase.
  int analyses() const { return analyses_; }
  int reuses() const { return reuses_; }
  double analyse_ms() const { return analyse_ms_; }
  double factorize_ms() const { return factorize_ms_; }
  double solve_ms() const { return solve_ms_; }

 private:
  struct Impl;
  LinearSolver kind_;
  std::unique_ptr<Impl> impl_;
  std::vector<int> outer_, inner_;  // the analysed pattern
  int analyses_ = 0, reuses_ = 0;
  double analyse_ms_ = 0.0, factorize_ms_ = 0.0, solve_ms_ = 0.0;
};

}  // namespace gcmap
