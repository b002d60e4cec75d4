#include <cmath>

#include "gcmap/core/error.hpp"
#include "gcmap/graph/levenberg_marquardt.hpp"
#include "gcmap/graph/sparse_solver.hpp"
#include "gcmap/mapping/config.hpp"
#include "test_util.hpp"

namespace gcmap {
namespace {

// Lower triangle of a random symmetric positive definite n x n matrix with a band of `width`.
Eigen::SparseMatrix<double> random_spd(int n, int width, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<Eigen::Triplet<double>> t;
  for (int c = 0; c < n; ++c) {
    t.emplace_back(c, c, 2.0 * width + 1.0 + u(rng));  // diagonally dominant
    for (int r = c + 1; r < std::min(n, c + width + 1); ++r) t.emplace_back(r, c, u(rng));
  }
  Eigen::SparseMatrix<double> A(n, n);
  A.setFromTriplets(t.begin(), t.end());
  return A;
}

std::vector<LinearSolver> built_solvers() {
  std::vector<LinearSolver> kinds{LinearSolver::eigen};
  if (cholmod_available()) kinds.push_back(LinearSolver::cholmod);
  return kinds;
}

TEST(SparseSolver, ReusedAnalysisEqualsFreshAnalysis) {
  const Eigen::VectorXd rhs = Eigen::VectorXd::LinSpaced(60, -1.0, 2.0);
  for (LinearSolver kind : built_solvers()) {
    SCOPED_TRACE(linear_solver_name(kind));
    SparseSolver reused(kind);
    ASSERT_TRUE(reused.factorize(random_spd(60, 7, 1)));
    const Eigen::SparseMatrix<double> A = random_spd(60, 7, 2);  // same pattern, other values
    ASSERT_TRUE(reused.factorize(A));
    EXPECT_EQ(reused.analyses(), 1);
    EXPECT_EQ(reused.reuses(), 1);
    SparseSolver fresh(kind);
    ASSERT_TRUE(fresh.factorize(A));
    const Eigen::VectorXd x = reused.solve(rhs);
    EXPECT_LT((x - fresh.solve(rhs)).norm(), 1e-12 * x.norm());
    EXPECT_LT((A.selfadjointView<Eigen::Lower>() * x - rhs).norm(), 1e-12 * rhs.norm());
    // A new pattern is analysed again.
    const Eigen::SparseMatrix<double> B = random_spd(60, 3, 3);
    ASSERT_TRUE(reused.factorize(B));
    EXPECT_EQ(reused.analyses(), 2);
    const Eigen::VectorXd y = reused.solve(rhs);
    EXPECT_LT((B.selfadjointView<Eigen::Lower>() * y - rhs).norm(), 1e-12 * rhs.norm());
  }
}

TEST(SparseSolver, AnalysisAheadFromThePatternAloneServesTheFactorization) {
  const Eigen::SparseMatrix<double> A = random_spd(60, 7, 8);
  Eigen::SparseMatrix<double> pattern = A;
  std::fill(pattern.valuePtr(), pattern.valuePtr() + pattern.nonZeros(), std::nan(""));  // not read
  const Eigen::VectorXd rhs = Eigen::VectorXd::LinSpaced(60, -2.0, 1.0);
  for (LinearSolver kind : built_solvers()) {
    SCOPED_TRACE(linear_solver_name(kind));
    SparseSolver ahead(kind);
    EXPECT_TRUE(ahead.analyse(pattern));
    EXPECT_FALSE(ahead.analyse(pattern));  // already analysed
    ASSERT_TRUE(ahead.factorize(A));
    EXPECT_EQ(ahead.analyses(), 1);
    EXPECT_EQ(ahead.reuses(), 1);
    SparseSolver fresh(kind);
    ASSERT_TRUE(fresh.factorize(A));
    const Eigen::VectorXd x = ahead.solve(rhs);
    EXPECT_LT((x - fresh.solve(rhs)).norm(), 1e-12 * x.norm());
  }
}

TEST(SparseSolver, AutoTakesCholmodFromItsSizeOnAndSolvesAlike) {
  SparseSolver solver(LinearSolver::automatic);
  const Eigen::SparseMatrix<double> small = random_spd(60, 7, 5), large = random_spd(3000, 49, 6);  // 147k non-zeros
  ASSERT_GE(large.nonZeros(), kAutoCholmodNonZeros);
  ASSERT_TRUE(solver.factorize(small));
  EXPECT_EQ(solver.active(), LinearSolver::eigen);
  ASSERT_TRUE(solver.factorize(large));
  EXPECT_EQ(solver.active(), cholmod_available() ? LinearSolver::cholmod : LinearSolver::eigen);
  const Eigen::VectorXd rhs = Eigen::VectorXd::LinSpaced(3000, -1.0, 2.0);
  const Eigen::VectorXd x = solver.solve(rhs);
  SparseSolver eigen(LinearSolver::eigen);
  ASSERT_TRUE(eigen.factorize(large));
  EXPECT_LT((x - eigen.solve(rhs)).norm(), 1e-12 * x.norm());
  // Once taken, CHOLMOD stays for smaller systems too (a run's systems only grow).
  ASSERT_TRUE(solver.factorize(small));
  EXPECT_EQ(solver.active(), cholmod_available() ? LinearSolver::cholmod : LinearSolver::eigen);
}

TEST(SparseSolver, SingularMatrixIsNotFactorizedAndTheNextTryReusesTheAnalysis) {
  const Eigen::SparseMatrix<double> good = random_spd(30, 4, 4);
  Eigen::SparseMatrix<double> singular = good;
  for (int c = 0; c < 30; ++c)
    for (Eigen::SparseMatrix<double>::InnerIterator it(singular, c); it; ++it)
      if (it.row() == 12 || it.col() == 12) it.valueRef() = 0.0;  // a zero row and column, same pattern
  const Eigen::VectorXd rhs = Eigen::VectorXd::Ones(30);
  for (LinearSolver kind : built_solvers()) {
    SCOPED_TRACE(linear_solver_name(kind));
    SparseSolver solver(kind);
    EXPECT_FALSE(solver.factorize(singular));
    ASSERT_TRUE(solver.factorize(good));  // as LM's next, more damped trial
    EXPECT_EQ(solver.analyses(), 1);
    const Eigen::VectorXd x = solver.solve(rhs);
    EXPECT_LT((good.selfadjointView<Eigen::Lower>() * x - rhs).norm(), 1e-12 * rhs.norm());
  }
  if (!cholmod_available()) EXPECT_THROW(SparseSolver{LinearSolver::cholmod}, Error);
}

// An inconsistent pose graph: a chain of 12 poses with noisy odometry and loop measurements.
struct ChainProblem {
  FactorGraph graph;
  Values initial;
};

ChainProblem noisy_chain() {
  std::mt19937_64 rng(31);
  std::vector<Eigen::Isometry3d> truth;
  for (int k = 0; k < 12; ++k) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = so3_exp(Eigen::Vector3d(0, 0, k * M_PI / 6));
    T.translation() = T.linear() * Eigen::Vector3d(8, 0, 0);
    truth.push_back(T);
  }
  ChainProblem p;
  Matrix6d info = Matrix6d::Identity();
  info.diagonal() << 400, 400, 400, 100, 100, 100;
  auto measure = [&](int i, int j) {
    const Eigen::Isometry3d z = truth[i].inverse() * truth[j] * test::random_pose(rng, 0.01, 0.05);
    p.graph.add(std::make_shared<RelativePoseFactor>(i, j, z, info));
  };
  for (int k = 0; k < 12; ++k) {
    measure(k, (k + 1) % 12);
    if (k % 3 == 0) measure(k, (k + 5) % 12);
  }
  for (int k = 0; k < 12; ++k) p.initial[k] = k == 0 ? truth[0] : truth[k] * test::random_pose(rng, 0.1, 0.5);
  return p;
}

TEST(LevenbergMarquardt, CholmodReachesTheSamePosesAsEigen) {
  if (!cholmod_available()) GTEST_SKIP() << "built without CHOLMOD (libsuitesparse-dev)";
  const ChainProblem p = noisy_chain();
  std::map<LinearSolver, Values> result;
  for (LinearSolver kind : {LinearSolver::eigen, LinearSolver::cholmod}) {
    LMConfig config;
    config.linear_solver = kind;
    config.relative_error_tol = config.step_tol = 0.0;
    Values values = p.initial;
    const LMResult r = LevenbergMarquardt(config).optimize(p.graph, values, {0});
    EXPECT_TRUE(r.converged);
    EXPECT_GT(r.final_error, 1e-3);  // inconsistent: the optimum is not trivial
    result[kind] = values;
  }
  for (int k = 0; k < 12; ++k) {
    const Eigen::Isometry3d& e = result[LinearSolver::eigen].at(k);
    const Eigen::Isometry3d& c = result[LinearSolver::cholmod].at(k);
    EXPECT_LT((e.matrix() - c.matrix()).cwiseAbs().maxCoeff(), 1e-9) << k;
  }
}

TEST(LevenbergMarquardt, KeepsItsAnalysisWhileThePatternStays) {
  for (LinearSolver kind : built_solvers()) {
    SCOPED_TRACE(linear_solver_name(kind));
    ChainProblem p = noisy_chain();
    LMConfig config;
    config.linear_solver = kind;
    LevenbergMarquardt lm(config);
    EXPECT_EQ(lm.optimize(p.graph, p.initial, {0}).analyses, 1);
    EXPECT_EQ(lm.optimize(p.graph, p.initial, {0}).analyses, 0);  // same graph again
    p.graph.add(std::make_shared<RelativePoseFactor>(2, 7, p.initial.at(2).inverse() * p.initial.at(7), Matrix6d::Identity()));
    EXPECT_EQ(lm.optimize(p.graph, p.initial, {0}).analyses, 1);  // a new block pair
  }
}

TEST(LevenbergMarquardt, CholmodReportsTheUnconstrainedPose) {
  if (!cholmod_available()) GTEST_SKIP() << "built without CHOLMOD (libsuitesparse-dev)";
  ChainProblem p = noisy_chain();
  p.initial[40] = Eigen::Isometry3d::Identity();  // a pose no factor touches
  LMConfig config;
  config.linear_solver = LinearSolver::cholmod;
  try {
    LevenbergMarquardt(config).optimize(p.graph, p.initial, {0});
    ADD_FAILURE();
  } catch (const Error& e) { EXPECT_NE(std::string(e.what()).find("pose 40"), std::string::npos) << e.what(); }
}

TEST(MappingConfig, LinearSolverKey) {
  EXPECT_EQ(MappingConfig{}.global.linear_solver, LinearSolver::automatic);
  try {
    MappingConfig::parse("global:\n  linear_solver: umfpack\n", "c.yaml");
    ADD_FAILURE();
  } catch (const Error& e) { EXPECT_NE(std::string(e.what()).find("global.linear_solver"), std::string::npos) << e.what(); }
  const MappingConfig a = MappingConfig::parse("global:\n  linear_solver: auto\n", "c.yaml");
  EXPECT_EQ(a.global.linear_solver, LinearSolver::automatic);
  EXPECT_EQ(MappingConfig::parse(a.to_yaml(), "dump").global.linear_solver, LinearSolver::automatic);
  if (cholmod_available()) {
    const MappingConfig c = MappingConfig::parse("global:\n  linear_solver: cholmod\n", "c.yaml");
    EXPECT_EQ(c.global.linear_solver, LinearSolver::cholmod);
    EXPECT_EQ(MappingConfig::parse(c.to_yaml(), "dump").global.linear_solver, LinearSolver::cholmod);
  } else {
    EXPECT_THROW(MappingConfig::parse("global:\n  linear_solver: cholmod\n", "c.yaml"), Error);
  }
}

}  // namespace
}  // namespace gcmap
