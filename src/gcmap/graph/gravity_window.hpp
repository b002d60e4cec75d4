#pragma once
// What an accelerometer says of gravity, for levelling the global graph. Between frames a, m and
// b (times T1 = t_m - t_a, T2 = t_b - t_m apart) whose odometry poses are known, the IMU's
// positions follow from gravity and the specific force it measured; the unknown velocities drop
// out of the two intervals together:
//   g (T1 + T2) / 2 = (p_b - p_m) / T2 - (p_m - p_a) / T1 + P_am / T1 - V_am - P_mb / T2,
// with V and P the velocity and position the specific force alone gives over an interval,
// integrated frame by frame (graph/imu_preintegration) from the odometry's rotation at each frame.
// Positions over seconds are what LiDAR odometry knows best, far better than velocities. All of it
// is linear in the accelerometer's bias: g T = c - M b_a (graph/gravity_factor.hpp's GravityWindow).
#include <Eigen/Geometry>
#include <optional>
#include <vector>

#include "gcmap/core/imu_sample.hpp"
#include "gcmap/graph/gravity_factor.hpp"
#include "gcmap/graph/imu_preintegration.hpp"

namespace gcmap {

// A frame's odometry pose (LiDAR) at its stamp.
struct OdometryFrame {
  double stamp = 0.0;
  Eigen::Isometry3d T_odom_lidar = Eigen::Isometry3d::Identity();
};

// The velocity V and position P the specific force alone gives from frame i0 to i1 (odometry
// frame, starting at rest; each interval turned by the odometry's rotation at its start), and their
// derivatives by the accelerometer's bias. samples as for gravity_window, covering the frames.
struct ForceIntegral {
  Eigen::Vector3d V = Eigen::Vector3d::Zero(), P = Eigen::Vector3d::Zero();
  Eigen::Matrix3d dV = Eigen::Matrix3d::Zero(), dP = Eigen::Matrix3d::Zero();
};
ForceIntegral integrate_force(const std::vector<ImuSample>& samples, const std::vector<OdometryFrame>& frames, size_t i0,
                              size_t i1, const ImuConfig& imu);

// The window over frames a < m < b, expressed in the frame of the submap whose odometry pose is
// T_odom_submap. samples: on the LiDAR's clock, in the IMU frame, stamps increasing. Empty when the
// samples do not cover the window.
std::optional<GravityWindow> gravity_window(const std::vector<ImuSample>& samples, const std::vector<OdometryFrame>& frames,
                                            size_t a, size_t m, size_t b, const ImuConfig& imu,
                                            const Eigen::Isometry3d& T_odom_submap);

}  // namespace gcmap
