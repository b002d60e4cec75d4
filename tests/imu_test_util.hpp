#pragma once
// An exact, smooth trajectory and the IMU samples it makes, for the IMU tests.
#include <cmath>
#include <vector>

#include "gcmap/graph/imu_preintegration.hpp"

namespace gcmap::test {

// p(t) and R(t) = Rz(yaw) Ry(pitch) Rx(roll) made of sines: every derivative exact.
struct SmoothTrajectory {
  Eigen::Vector3d position(double t) const {
    return {3.0 * std::sin(1.3 * t) + 2.0 * t, 2.0 * std::cos(0.9 * t), 0.5 * t * t + 0.3 * std::sin(2.0 * t)};
  }
  Eigen::Vector3d velocity(double t) const {
    return {3.9 * std::cos(1.3 * t) + 2.0, -1.8 * std::sin(0.9 * t), t + 0.6 * std::cos(2.0 * t)};
  }
  Eigen::Vector3d acceleration(double t) const {
    return {-5.07 * std::sin(1.3 * t), -1.62 * std::cos(0.9 * t), 1.0 - 1.2 * std::sin(2.0 * t)};
  }
  // yaw, pitch, roll and their rates.
  Eigen::Vector3d angles(double t) const {
    return {0.5 * std::sin(1.1 * t) + 0.3 * t, 0.2 * std::sin(0.7 * t), 0.1 * std::cos(1.5 * t)};
  }
  Eigen::Vector3d rates(double t) const {
    return {0.55 * std::cos(1.1 * t) + 0.3, 0.14 * std::cos(0.7 * t), -0.15 * std::sin(1.5 * t)};
  }
  Eigen::Matrix3d rotation(double t) const {
    const Eigen::Vector3d a = angles(t);
    return (Eigen::AngleAxisd(a[0], Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(a[1], Eigen::Vector3d::UnitY()) *
            Eigen::AngleAxisd(a[2], Eigen::Vector3d::UnitX()))
        .toRotationMatrix();
  }
  // Body-frame angular velocity: R^T dR/dt by the product rule.
  Eigen::Vector3d gyro(double t) const {
    const Eigen::Vector3d a = angles(t), r = rates(t);
    const Eigen::Matrix3d Rz = Eigen::AngleAxisd(a[0], Eigen::Vector3d::UnitZ()).toRotationMatrix();
    const Eigen::Matrix3d Ry = Eigen::AngleAxisd(a[1], Eigen::Vector3d::UnitY()).toRotationMatrix();
    const Eigen::Matrix3d Rx = Eigen::AngleAxisd(a[2], Eigen::Vector3d::UnitX()).toRotationMatrix();
    const Eigen::Matrix3d dR = Rz * skew(Eigen::Vector3d(Eigen::Vector3d::UnitZ())) * r[0] * Ry * Rx +
                               Rz * Ry * skew(Eigen::Vector3d(Eigen::Vector3d::UnitY())) * r[1] * Rx +
                               Rz * Ry * Rx * skew(Eigen::Vector3d(Eigen::Vector3d::UnitX())) * r[2];
    const Eigen::Matrix3d W = (Rz * Ry * Rx).transpose() * dR;
    return {W(2, 1), W(0, 2), W(1, 0)};
  }
  Eigen::Vector3d accel(double t) const { return rotation(t).transpose() * (acceleration(t) - gravity_vector()); }

  NavState state(double t, const ImuBias& bias = {}) const {
    NavState s;
    s.T_world_imu.linear() = rotation(t);
    s.T_world_imu.translation() = position(t);
    s.velocity = velocity(t);
    s.bias = bias;
    return s;
  }
  // Samples at `rate` Hz from t0 to t1 (both included), biased by `bias`.
  std::vector<ImuSample> samples(double t0, double t1, double rate, const ImuBias& bias = {}) const {
    std::vector<ImuSample> out;
    const int n = static_cast<int>(std::lround((t1 - t0) * rate));
    for (int k = 0; k <= n; ++k) {
      const double t = t0 + k / rate;
      out.push_back({t, gyro(t) + bias.gyro, accel(t) + bias.accel});
    }
    return out;
  }
};

}  // namespace gcmap::test
