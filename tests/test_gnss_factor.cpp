#include <cmath>

#include "gcmap/core/error.hpp"
#include "gcmap/graph/gnss_factor.hpp"
#include "gcmap/graph/levenberg_marquardt.hpp"
#include "gcmap/mapping/global_mapper.hpp"
#include "test_util.hpp"

namespace gcmap {
namespace {

TEST(GnssFactor, JacobianMatchesNumericDifferentiation) {
  std::mt19937_64 rng(7);
  for (int trial = 0; trial < 20; ++trial) {
    const Eigen::Isometry3d T = test::random_pose(rng, 3.0, 50.0);
    const Eigen::Vector3d p = 3.0 * Eigen::Vector3d::Random(), z = 50.0 * Eigen::Vector3d::Random();
    const GnssPositionFactor f(0, p, z, Eigen::Vector3d(0.02, 0.03, 0.05));
    const Eigen::Matrix<double, 3, 6> J = f.jacobian(T);
    const double h = 1e-6;
    for (int k = 0; k < 6; ++k) {
      Vector6d d = Vector6d::Zero();
      d[k] = h;
      const Eigen::Vector3d numeric = (f.residual(T * se3_exp(d)) - f.residual(T * se3_exp(-d))) / (2 * h);
      EXPECT_LT((numeric - J.col(k)).norm(), 1e-6 * (1.0 + numeric.norm())) << "column " << k;
    }
  }
}

TEST(GnssFactor, LinearizationPredictsTheErrorOfASmallStep) {
  std::mt19937_64 rng(3);
  const Eigen::Isometry3d T = test::random_pose(rng, 1.0, 20.0);
  GnssPositionFactor f(0, Eigen::Vector3d(0.5, -0.2, 1.0), Eigen::Vector3d(3, 4, 5), Eigen::Vector3d(0.1, 0.1, 0.2));
  const Eigen::Isometry3d* poses[1] = {&T};
  FactorLinearization lin;
  f.linearize(poses, lin);
  EXPECT_NEAR(lin.error, std::pow(f.whitened_norm(T), 2), 1e-9 * lin.error);
  Vector6d d;
  d << 1e-4, -2e-4, 3e-4, 1e-3, 2e-3, -1e-3;
  const Eigen::Isometry3d moved = T * se3_exp(d);
  const Eigen::Isometry3d* trial[1] = {&moved};
  const double model = lin.error + 2.0 * lin.b.head<6>().dot(d) + d.dot(lin.H.topLeftCorner<6, 6>() * d);
  EXPECT_NEAR(f.trial_error(trial), model, 1e-6 * lin.error);
}

TEST(GnssFactor, HuberWeightBoundsAnOutliersPull) {
  const Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  const Eigen::Isometry3d* poses[1] = {&T};
  GnssPositionFactor f(0, Eigen::Vector3d::Zero(), Eigen::Vector3d(10, 0, 0), Eigen::Vector3d::Constant(0.02),
                       RobustKernel::huber(3.0));
  FactorLinearization lin;
  f.linearize(poses, lin);
  EXPECT_NEAR(f.weight(), 3.0 / 500.0, 1e-12);  // 10 m at 2 cm is 500 sigmas
  // The gradient's size is that of a residual of 3 sigmas, whatever the outlier's size.
  EXPECT_NEAR(lin.b.head<6>().norm(), 3.0 / 0.02, 1e-6);
}

TEST(GnssFactor, OptimizingOnePoseOnNonCollinearFixesRecoversIt) {
  std::mt19937_64 rng(11);
  const Eigen::Isometry3d truth = test::random_pose(rng, 0.3, 10.0);
  FactorGraph g;
  const Eigen::Vector3d antennas[4] = {{5, 0, 0}, {0, 5, 0}, {0, 0, 5}, {-5, -5, 1}};
  for (const Eigen::Vector3d& p : antennas)
    g.add(std::make_shared<GnssPositionFactor>(0, p, truth * p, Eigen::Vector3d::Constant(0.01)));
  Values v{{0, Eigen::Isometry3d::Identity()}};
  LevenbergMarquardt lm;
  lm.optimize(g, v);
  EXPECT_LT(test::translation_error(v.at(0), truth), 1e-6);
  EXPECT_LT(test::rotation_error_deg(v.at(0), truth), 1e-5);
}

TEST(GnssAlignment, YawAndTranslationRecoveredDespiteOutliers) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(-50.0, 50.0);
  Eigen::Isometry3d truth = Eigen::Isometry3d::Identity();
  truth.linear() = Eigen::AngleAxisd(2.1, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  truth.translation() << 120.0, -40.0, 3.0;
  std::vector<Eigen::Vector3d> world, enu;
  for (int i = 0; i < 50; ++i) {
    world.emplace_back(u(rng), u(rng), 0.05 * u(rng));
    enu.push_back(truth * world.back());
    if (i % 10 == 3) enu.back() += Eigen::Vector3d(12.0, -7.0, 4.0);  // 10 % multipath
  }
  std::vector<char> inliers;
  const Eigen::Isometry3d T = fit_yaw_translation(world, enu, std::vector<double>(world.size(), 1.0), &inliers);
  EXPECT_LT(test::translation_error(T, truth), 1e-9);
  EXPECT_LT(test::rotation_error_deg(T, truth), 1e-9);
  for (int i = 0; i < 50; ++i) EXPECT_EQ(inliers[i], i % 10 != 3) << i;
  EXPECT_THROW(fit_yaw_translation({world[0]}, {enu[0]}, {1.0}), Error);
}

}  // namespace
}  // namespace gcmap
