#pragma once
// One IMU measurement, as every layer passes it (readers, simulator, preintegration).
#include <Eigen/Core>
#include <Eigen/Geometry>

namespace gcmap {

constexpr double kStandardGravity = 9.80665;  // m/s^2

struct ImuSample {
  double stamp = 0.0;     // s
  Eigen::Vector3d gyro;   // rad/s, IMU frame
  Eigen::Vector3d accel;  // m/s^2, IMU frame, specific force (at rest: +g along the IMU's up)
};

// What the gyro says a sensor turned between two instants: R_t0_t1 of the LiDAR frame, bias
// removed, with the variance (rad^2, per axis) of each of its angles.
struct GyroRotation {
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  double variance = 0.0;

  // This rotation followed by `next`. Their white noise is independent, so the variances add (the
  // share of a bias error, correlated, is small beside it over seconds).
  GyroRotation then(const GyroRotation& next) const { return {R * next.R, variance + next.variance}; }
};

}  // namespace gcmap
