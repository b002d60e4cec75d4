#include <cmath>

#include "gcmap/core/error.hpp"
#include "gcmap/graph/gravity_factor.hpp"
#include "gcmap/graph/imu_preintegration.hpp"
#include "gcmap/graph/levenberg_marquardt.hpp"
#include "test_util.hpp"

namespace gcmap {
namespace {

// A window that measures gravity g_pose (pose frame) when the bias is `bias`, with a bias
// dependence M of a second of turning motion.
GravityWindow window_for(const Eigen::Vector3d& g_pose, const Eigen::Vector3d& bias, int submap) {
  GravityWindow w;
  w.submap = submap;
  w.duration = 2.0;
  w.M = -2.0 * Eigen::AngleAxisd(0.3, Eigen::Vector3d(0.2, 0.1, 1.0).normalized()).toRotationMatrix();
  w.c = w.duration * g_pose + w.M * bias;
  w.sigma = 3e-4;
  return w;
}

Eigen::Isometry3d bias_pose(const Eigen::Vector3d& b) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = b;
  return T;
}

TEST(GravityFactor, JacobiansMatchNumericDifferentiation) {
  std::mt19937_64 rng(17);
  for (int trial = 0; trial < 20; ++trial) {
    const Eigen::Isometry3d T = test::random_pose(rng, 0.5, 30.0), B = bias_pose(0.05 * Eigen::Vector3d::Random());
    const GravityFactor f(window_for(9.8 * Eigen::Vector3d::Random().normalized(), Eigen::Vector3d::Zero(), 0), -1, 9.8);
    const Eigen::Matrix<double, 3, 12> J = f.jacobian(T, B);
    const HeadingPositionFactor h(0, test::random_pose(rng, 0.5, 30.0), 0.01);
    const Eigen::Matrix<double, 4, 6> Jh = h.jacobian(T);
    const double eps = 1e-6;
    for (int k = 0; k < 6; ++k) {
      Vector6d d = Vector6d::Zero();
      d[k] = eps;
      const Eigen::Vector3d num_pose = (f.residual(T * se3_exp(d), B) - f.residual(T * se3_exp(-d), B)) / (2 * eps);
      const Eigen::Vector3d num_bias = (f.residual(T, B * se3_exp(d)) - f.residual(T, B * se3_exp(-d))) / (2 * eps);
      EXPECT_LT((num_pose - J.col(k)).norm(), 1e-6 * (1.0 + num_pose.norm())) << "pose column " << k;
      EXPECT_LT((num_bias - J.col(6 + k)).norm(), 1e-6 * (1.0 + num_bias.norm())) << "bias column " << k;
      const Eigen::Vector4d num_h = (h.residual(T * se3_exp(d)) - h.residual(T * se3_exp(-d))) / (2 * eps);
      EXPECT_LT((num_h - Jh.col(k)).norm(), 1e-6 * (1.0 + num_h.norm())) << "heading column " << k;
    }
  }
}

TEST(GravityFactor, LinearizationPredictsTheErrorOfASmallStep) {
  std::mt19937_64 rng(4);
  const Eigen::Isometry3d T = test::random_pose(rng, 0.3, 5.0), B = bias_pose(Eigen::Vector3d(0.02, -0.01, 0.03));
  GravityFactor f(window_for(Eigen::Vector3d(0.5, -0.3, -9.7), Eigen::Vector3d::Zero(), 0), -1, 9.80665);
  const Eigen::Isometry3d* poses[2] = {&T, &B};
  FactorLinearization lin;
  f.linearize(poses, lin);
  Vector12d d;
  d << 1e-4, -2e-4, 3e-4, 1e-3, 2e-3, -1e-3, 0, 0, 0, 1e-3, -2e-3, 1e-3;
  const Eigen::Isometry3d moved = T * se3_exp(d.head<6>()), moved_bias = B * se3_exp(d.tail<6>());
  const Eigen::Isometry3d* trial[2] = {&moved, &moved_bias};
  const double model = lin.error + 2.0 * lin.b.dot(d) + d.dot(lin.H * d);
  EXPECT_NEAR(f.trial_error(trial), model, 1e-3 * lin.error);
}

// Poses a rigid chain apart, leaning together, with a biased accelerometer: the gravity seen in
// each levels them and recovers the bias, because the poses face different ways (a bias fixed to
// the body turns with it, gravity does not); the held heading and position keep the rest.
TEST(GravityFactor, LevelsALeaningChainAndRecoversTheAccelerometerBias) {
  const Eigen::Vector3d bias(0.04, -0.03, 0.02);
  const Eigen::Isometry3d lean(Eigen::AngleAxisd(0.05, Eigen::Vector3d(1, 2, 0).normalized()));
  FactorGraph g;
  std::vector<Eigen::Isometry3d> truth;
  Values v;
  for (int k = 0; k < 4; ++k) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = Eigen::AngleAxisd(1.6 * k, Eigen::Vector3d::UnitZ()).toRotationMatrix() *
                 Eigen::AngleAxisd(0.02 * k, Eigen::Vector3d::UnitX()).toRotationMatrix();
    T.translation() << 10.0 * std::cos(k), 10.0 * std::sin(k), 0.3 * k;
    truth.push_back(T);
    v[k] = lean * T;
    const Eigen::Vector3d g_pose = T.linear().transpose() * gravity_vector(9.80665);
    g.add(std::make_shared<GravityFactor>(window_for(g_pose, bias, k), -1, 9.80665));
    if (k) g.add(std::make_shared<RelativePoseFactor>(k - 1, k, truth[k - 1].inverse() * T, Matrix6d::Identity() * 1e6));
  }
  v[-1] = Eigen::Isometry3d::Identity();
  g.add(std::make_shared<AccelBiasPriorFactor>(-1, 0.1));
  g.add(std::make_shared<HeadingPositionFactor>(0, v.at(0), 1e-4));
  LevenbergMarquardt lm;
  lm.optimize(g, v);
  for (int k = 0; k < 4; ++k) {
    const Eigen::Vector3d up = v.at(k).linear().transpose() * Eigen::Vector3d::UnitZ();
    const Eigen::Vector3d true_up = truth[k].linear().transpose() * Eigen::Vector3d::UnitZ();
    EXPECT_LT(std::acos(std::min(1.0, up.dot(true_up))), 1e-4) << "pose " << k;
  }
  EXPECT_LT((v.at(-1).translation() - bias).norm(), 1e-4);
  EXPECT_LT(so3_log(v.at(-1).linear()).norm(), 1e-9);
  EXPECT_LT((v.at(0).translation() - (lean * truth[0]).translation()).norm(), 1e-6);
  EXPECT_THROW(HeadingPositionFactor(0, Eigen::Isometry3d(Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitY())), 0.01), Error);
}

}  // namespace
}  // namespace gcmap
