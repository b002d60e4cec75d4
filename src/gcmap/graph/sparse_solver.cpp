#include "gcmap/graph/sparse_solver.hpp"

#include <Eigen/SparseCholesky>
#include <algorithm>
#include <variant>

#include "gcmap/core/error.hpp"
#include "gcmap/core/timer.hpp"

#ifdef GCMAP_WITH_CHOLMOD
#include <Eigen/CholmodSupport>
#endif

namespace gcmap {

const char* linear_solver_name(LinearSolver solver) {
  switch (solver) {
    case LinearSolver::eigen: return "eigen";
    case LinearSolver::cholmod: return "cholmod";
    case LinearSolver::automatic: return "auto";
  }
  return "?";
}

bool cholmod_available() {
#ifdef GCMAP_WITH_CHOLMOD
  return true;
#else
  return false;
#endif
}

using SparseMatrix = Eigen::SparseMatrix<double>;
using EigenLdlt = Eigen::SimplicialLDLT<SparseMatrix, Eigen::Lower>;
#ifdef GCMAP_WITH_CHOLMOD
using CholmodLlt = Eigen::CholmodSupernodalLLT<SparseMatrix, Eigen::Lower>;
struct SparseSolver::Impl {
  std::variant<EigenLdlt, CholmodLlt> solver;
};
#else
struct SparseSolver::Impl {
  std::variant<EigenLdlt> solver;
};
#endif

SparseSolver::SparseSolver(LinearSolver kind)
    : kind_(kind), active_(kind == LinearSolver::automatic ? LinearSolver::eigen : kind), impl_(std::make_unique<Impl>()) {
  if (kind_ == LinearSolver::cholmod && !cholmod_available())
    throw Error("linear_solver: cholmod asked for, but this build has no CHOLMOD (SuiteSparse)");
  if (active_ == LinearSolver::cholmod) use_cholmod();
}

void SparseSolver::use_cholmod() {
#ifdef GCMAP_WITH_CHOLMOD
  // Silent: a damping trial that is not positive definite is an expected outcome for LM.
  impl_->solver.emplace<CholmodLlt>().cholmod().print = 0;
  active_ = LinearSolver::cholmod;
#endif
}

SparseSolver::~SparseSolver() = default;
SparseSolver::SparseSolver(SparseSolver&&) noexcept = default;
SparseSolver& SparseSolver::operator=(SparseSolver&&) noexcept = default;

bool SparseSolver::analyse(const SparseMatrix& A) {
  const auto* outer = A.outerIndexPtr();
  const auto* inner = A.innerIndexPtr();
  const size_t cols = static_cast<size_t>(A.outerSize()) + 1, nnz = static_cast<size_t>(A.nonZeros());
  if (A.isCompressed() && outer_.size() == cols && inner_.size() == nnz && std::equal(outer_.begin(), outer_.end(), outer) &&
      std::equal(inner_.begin(), inner_.end(), inner))
    return false;
  Stopwatch w;
  if (kind_ == LinearSolver::automatic && active_ == LinearSolver::eigen && cholmod_available() &&
      A.nonZeros() >= kAutoCholmodNonZeros)
    use_cholmod();  // a run's systems only grow: no way back
  std::visit([&](auto& s) { s.analyzePattern(A); }, impl_->solver);
  outer_.clear();
  inner_.clear();
  if (A.isCompressed()) {  // an uncompressed matrix is analysed every time
    outer_.assign(outer, outer + cols);
    inner_.assign(inner, inner + nnz);
  }
  ++analyses_;
  analyse_ms_ += w.ms();
  return true;
}

bool SparseSolver::factorize(const SparseMatrix& A) {
  if (!analyse(A)) ++reuses_;
  Stopwatch w;
  const bool ok = std::visit(
      [&](auto& s) {
        s.factorize(A);
        return s.info() == Eigen::Success;
      },
      impl_->solver);
  factorize_ms_ += w.ms();
  return ok;
}

Eigen::VectorXd SparseSolver::solve(const Eigen::VectorXd& rhs) {
  Stopwatch w;
  Eigen::VectorXd x = std::visit([&](auto& s) -> Eigen::VectorXd { return s.solve(rhs); }, impl_->solver);
  solve_ms_ += w.ms();
  return x;
}

}  // namespace gcmap
