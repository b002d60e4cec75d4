#include <gtest/gtest.h>

#include <cmath>

#include "gcmap/core/se3.hpp"
#include "gcmap/graph/gravity_window.hpp"
#include "gcmap/sim/imu.hpp"

namespace gcmap {
namespace {

// A rig that turns, climbs and rolls over 5 s, its LiDAR poses every 0.01 s (the IMU's knots).
std::vector<Eigen::Isometry3d> rig_poses() {
  std::vector<Eigen::Isometry3d> out;
  for (int k = 0; k <= 500; ++k) {
    const double t = 0.01 * k;
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = (Eigen::AngleAxisd(0.6 * t + 0.2 * std::sin(2.0 * t), Eigen::Vector3d::UnitZ()) *
                  Eigen::AngleAxisd(0.05 * std::sin(1.3 * t), Eigen::Vector3d::UnitY()) *
                  Eigen::AngleAxisd(0.08 * std::cos(1.7 * t), Eigen::Vector3d::UnitX()))
                     .toRotationMatrix();
    T.translation() << 8.0 * std::sin(0.6 * t), 8.0 * (1.0 - std::cos(0.6 * t)), 0.3 * t + 0.05 * std::sin(3.0 * t);
    out.push_back(T);
  }
  return out;
}

// Exact odometry in a frame tilted against the world and an exact IMU: the window measures the
// world's gravity in the submap frame; with a biased accelerometer, it does at the bias.
TEST(GravityWindow, MeasuresGravityInTheSubmapFrameAndItsBiasDependence) {
  const std::vector<Eigen::Isometry3d> poses = rig_poses();
  ImuConfig imu;
  imu.x = 0.04, imu.y = -0.02, imu.z = 0.03, imu.yaw_deg = 20.0;
  const sim::ImuTrajectory trajectory(poses, 0.01, imu.T_lidar_imu());
  const Eigen::Vector3d bias(0.05, -0.03, 0.02);
  std::vector<ImuSample> exact, biased;
  for (int k = 0; k <= 2000; ++k) {
    exact.push_back(trajectory.measure(k / 400.0));
    biased.push_back(exact.back());
    biased.back().accel += bias;
  }
  const Eigen::Isometry3d T_world_odom(Eigen::AngleAxisd(0.07, Eigen::Vector3d(1, -2, 0).normalized()));
  std::vector<OdometryFrame> frames;
  for (int f = 0; f <= 49; ++f) frames.push_back({0.1 * f, T_world_odom.inverse() * poses[10 * f]});
  const Eigen::Isometry3d T_odom_submap = frames[20].T_odom_lidar;
  const Eigen::Vector3d truth = ((T_world_odom * T_odom_submap).linear().transpose() * gravity_vector()).eval();
  const auto w = gravity_window(exact, frames, 5, 25, 45, imu, T_odom_submap);
  ASSERT_TRUE(w.has_value());
  EXPECT_NEAR(w->duration, 2.0, 1e-12);
  // The trapezoid rule over 400 Hz samples and the spline between the knots leave millimetres per second squared.
  EXPECT_LT((w->gravity(Eigen::Vector3d::Zero()) - truth).norm(), 5e-3) << w->gravity(Eigen::Vector3d::Zero()).transpose();
  const auto wb = gravity_window(biased, frames, 5, 25, 45, imu, T_odom_submap);
  ASSERT_TRUE(wb.has_value());
  EXPECT_GT((wb->gravity(Eigen::Vector3d::Zero()) - truth).norm(), 0.02);  // the bias shows
  EXPECT_LT((wb->gravity(bias) - truth).norm(), 5e-3);                     // and M accounts for it
  EXPECT_GT(w->sigma, 0.0);
  // Not covered by the samples, or too short: no window.
  EXPECT_FALSE(gravity_window(std::vector<ImuSample>(exact.begin() + 400, exact.end()), frames, 5, 25, 45, imu, T_odom_submap));
  EXPECT_FALSE(gravity_window(exact, frames, 5, 6, 7, imu, T_odom_submap));
}

}  // namespace
}  // namespace gcmap
