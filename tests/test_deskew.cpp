#include <gtest/gtest.h>

#include <cstdio>
#include <random>

#include "gcmap/core/deskew.hpp"
#include "gcmap/core/error.hpp"
#include "test_util.hpp"

namespace gcmap::test {
namespace {

// A static scene seen by a sensor moving at constant velocity during a 0.1 s sweep: each point is
// measured in the sensor frame of its own time. Deskewing restores the scene in the frame at t = 0.
struct Sweep {
  PointCloud scene;     // in the frame at t = 0
  PointCloud measured;  // as the sensor reports it
};

Sweep make_sweep(const Vector6d& velocity, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-40.f, 40.f);
  Sweep s;
  const int n = 2000;
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3f p(u(rng), u(rng), u(rng) * 0.2f);
    const float t = 0.1f * float(i / 10) / float(n / 10);  // columns of 10 points share a time
    const Eigen::Isometry3d T_0_t = se3_exp(double(t) * velocity);
    s.scene.points.push_back(p);
    s.measured.points.push_back((T_0_t.inverse() * p.cast<double>()).cast<float>());
    s.measured.times.push_back(t);
  }
  return s;
}

double max_error(const PointCloud& a, const PointCloud& b) {
  double e = 0;
  for (size_t i = 0; i < a.size(); ++i) e = std::max(e, double((a.points[i] - b.points[i]).norm()));
  return e;
}

TEST(Deskew, RestoresStaticSceneFromMovingSensor) {
  Vector6d v;
  v << 0.1, -0.05, 0.6, 15.0, 0.8, -0.3;  // turning at 0.6 rad/s while driving at 15 m/s
  Sweep s = make_sweep(v, 3);
  EXPECT_GT(max_error(s.measured, s.scene), 1.0);  // 1.5 m smear before
  PointCloud by_velocity = s.measured;
  deskew(by_velocity, v);
  EXPECT_LT(max_error(by_velocity, s.scene), 1e-4);

  // The same from the sweep's begin-to-end motion.
  PointCloud by_pose = s.measured;
  deskew(by_pose, se3_exp(0.1 * v), 0.1);
  EXPECT_LT(max_error(by_pose, s.scene), 1e-4);
  EXPECT_EQ(by_pose.times, s.measured.times);
}

TEST(Deskew, FollowsAYawRateThatGrowsOverTheSweep) {
  // Entering a corner at 15 m/s: the yaw rate grows from 0.5 to 1.5 rad/s within the sweep. The
  // sensor's true motion is integrated in fine steps (the forward velocity turns with the body).
  Vector6d v0, a;
  v0 << 0, 0, 0.5, 15.0, 0, 0;
  a << 0, 0, 10.0, 0, 0, 0;
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(-40.f, 40.f);
  PointCloud scene, measured;
  Eigen::Isometry3d T_0_t = Eigen::Isometry3d::Identity();
  const int steps = 10000;  // 10 us
  for (int k = 0; k < steps; ++k) {
    const double t = 0.1 * k / steps;
    const Eigen::Vector3f p(u(rng), u(rng), u(rng) * 0.2f);
    scene.points.push_back(p);
    measured.points.push_back((T_0_t.inverse() * p.cast<double>()).cast<float>());
    measured.times.push_back(float(t));
    T_0_t = T_0_t * se3_exp((v0 + (t + 0.05 / steps) * a) * (0.1 / steps));
  }
  PointCloud linear = measured;
  deskew(linear, v0, a);
  // Not exact: one twist turns at a constant curvature, the true path's curvature grows.
  EXPECT_LT(max_error(linear, scene), 0.02);
  // Constant velocity at the sweep's mean rate is off by half a metre at 40 m.
  PointCloud constant = measured;
  deskew(constant, Vector6d(v0 + 0.05 * a));
  EXPECT_GT(max_error(constant, scene), 0.3);
  // The same motion as a quadratic around the middle of the sweep (how a sweep is deskewed again
  // between the registered poses on both sides of it) follows it closer.
  PointCloud mid = measured;
  deskew(mid, Vector6d(v0 + 0.05 * a), a, 0.05);
  EXPECT_LT(max_error(mid, scene), 0.006);
  std::printf("yaw rate growing over the sweep: %.4f m (linear velocity), %.4f m (around the middle), %.3f m (constant)\n",
              max_error(linear, scene), max_error(mid, scene), max_error(constant, scene));
}

TEST(Deskew, AConstantVelocityDoesNotDependOnTheAnchor) {
  Vector6d v;
  v << 0.1, -0.05, 0.6, 15.0, 0.8, -0.3;
  Sweep s = make_sweep(v, 4);
  for (const double anchor : {0.0, 0.03, 0.1, -0.2}) {
    PointCloud c = s.measured;
    deskew(c, v, Vector6d::Zero(), anchor);
    EXPECT_LT(max_error(c, s.scene), 1e-4) << anchor;
  }
  PointCloud c = s.measured;
  EXPECT_THROW(deskew(c, v, Vector6d::Zero(), std::nan("")), Error);
}

TEST(Deskew, ADownsampledSweepGetsTheExactMotionWithinMicrometres) {
  // A downsampled sweep: every point has its own time, so poses come from a table (see deskew.cpp).
  // Each point is checked against its own exponential map, far points and a fast turn included.
  Vector6d v, a;
  v << 0.05, -0.02, 1.7, 15.0, 0.4, -0.1;
  a << 0.1, 0.0, 12.0, -2.0, 0.5, 0.0;
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-100.f, 100.f), time(0.f, 0.1f);
  PointCloud c;
  for (int i = 0; i < 20000; ++i) {
    c.points.emplace_back(u(rng), u(rng), u(rng) * 0.1f);
    c.times.push_back(time(rng));
  }
  for (const double anchor : {0.0, 0.05}) {
    PointCloud d = c;
    deskew(d, v, a, anchor);
    const auto T = [&](double t) { return se3_exp((t - anchor) * v + 0.5 * (t - anchor) * (t - anchor) * a); };
    const Eigen::Isometry3d T_0_anchor = T(0.0).inverse();
    double worst = 0.0, rounding = 0.0;
    for (size_t i = 0; i < c.size(); ++i) {
      const Eigen::Isometry3d T_0_t = T_0_anchor * T(c.times[i]);
      const Eigen::Vector3d exact = T_0_t * c.points[i].cast<double>();
      const Eigen::Vector3f in_float = T_0_t.linear().cast<float>() * c.points[i] + T_0_t.translation().cast<float>();
      worst = std::max(worst, (exact - d.points[i].cast<double>()).norm());
      rounding = std::max(rounding, (exact - in_float.cast<double>()).norm());
    }
    std::printf("anchor %.2f: table %.2g m, the exact pose in float %.2g m\n", anchor, worst, rounding);
    EXPECT_LT(worst, rounding + 1e-5) << anchor;  // the table's own error is microns at 140 m
  }
}

TEST(Deskew, BadTimesNeitherCrashNorAllocateATable) {
  Vector6d v;
  v << 0.0, 0.0, 1e200, 15.0, 0.0, 0.0;  // with a huge span, the rotation bound overflows
  PointCloud c;
  for (int i = 0; i < 4000; ++i) {
    c.points.emplace_back(float(i % 50), 1.f, 0.f);
    c.times.push_back(i == 7 ? std::nanf("") : (i == 8 ? 3e38f : 0.1f * float(i) / 4000.f));
  }
  PointCloud d = c;
  deskew(d, v);  // no table: an exponential map per time, exact where the time is 0
  EXPECT_EQ(d.points[0], c.points[0]);
  Vector6d slow = Vector6d::Zero();
  slow[3] = 1.0;
  c.times[8] = 0.05f;
  deskew(c, slow);  // a table; the NaN time takes its first pose (t = 0): the point stays
  EXPECT_EQ(c.points[7], Eigen::Vector3f(7.f, 1.f, 0.f));
  EXPECT_NEAR(c.points[8].x(), 8.05f, 1e-5);
}

TEST(Deskew, RotatesCovariancesAndRejectsBadInput) {
  Vector6d v = Vector6d::Zero();
  v[2] = M_PI / 2;  // 90 deg/s about z
  PointCloud c;
  c.points = {Eigen::Vector3f(1, 0, 0)};
  c.times = {1.0f};
  Eigen::Matrix3f cov = Eigen::Matrix3f::Zero();
  cov(0, 0) = 1;
  c.covs = {cov};
  deskew(c, v);
  EXPECT_LT((c.points[0] - Eigen::Vector3f(0, 1, 0)).norm(), 1e-6);
  EXPECT_NEAR(c.covs[0](1, 1), 1.f, 1e-6);

  PointCloud no_times;
  no_times.points = {Eigen::Vector3f(1, 2, 3)};
  deskew(no_times, v);
  EXPECT_EQ(no_times.points[0], Eigen::Vector3f(1, 2, 3));
  EXPECT_THROW(deskew(c, Eigen::Isometry3d::Identity(), 0.0), Error);
  c.times.push_back(0.f);
  EXPECT_THROW(deskew(c, v), Error);
}

TEST(Deskew, APoseTableRestoresTheSceneOfAnyMotion) {
  // An accelerating turn, sampled every millisecond as an IMU-driven motion is: each point moved
  // by the blend of its two neighbouring poses lands where the exact motion puts it.
  Vector6d v, a;
  v << 0.1, -0.2, 1.5, 14.0, 0.5, -0.3;
  a << 0.0, 0.3, -6.0, 2.0, -1.0, 0.0;
  const auto T_0 = [&](double t) { return se3_exp(t * v + 0.5 * t * t * a); };
  Sweep s = make_sweep(Vector6d::Zero(), 11);
  for (size_t i = 0; i < s.measured.size(); ++i)
    s.measured.points[i] = (T_0(s.measured.times[i]).inverse() * s.scene.points[i].cast<double>()).cast<float>();
  SweepPoses poses;
  poses.t0 = -0.002;
  for (int k = 0; k <= 104; ++k) poses.T.push_back(T_0(poses.t0 + poses.step * k));
  PointCloud c = s.measured;
  deskew(c, poses);
  EXPECT_LT(max_error(c, s.scene), 2e-4);
  // Between two poses the pose is their blend; beyond the table the nearest is held.
  EXPECT_LT(translation_error(poses.at(0.0505), T_0(0.0505)), 1e-4);
  EXPECT_LT(translation_error(poses.at(1.0), poses.T.back()), 1e-12);
  EXPECT_THROW(deskew(c, SweepPoses{}), Error);
}

}  // namespace
}  // namespace gcmap::test
