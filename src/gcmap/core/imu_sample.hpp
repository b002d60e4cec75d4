#pragma once
// One IMU measurement, as every layer passes it (readers, simulator, preintegration).
#include <Eigen/Core>

namespace gcmap {

constexpr double kStandardGravity = 9.80665;  // m/s^2

struct ImuSample {
  double stamp = 0.0;     // s
  Eigen::Vector3d gyro;   // rad/s, IMU frame
  Eigen::Vector3d accel;  // m/s^2, IMU frame, specific force (at rest: +g along the IMU's up)
};

}  // namespace gcmap
