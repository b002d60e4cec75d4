#include "gcmap/graph/imu_preintegration.hpp"

#include <algorithm>
#include <cmath>
#include <string>

#include "gcmap/core/error.hpp"

namespace gcmap {

Eigen::Matrix3d so3_right_jacobian(const Eigen::Vector3d& omega) { return so3_left_jacobian(-omega); }
Eigen::Matrix3d so3_right_jacobian_inverse(const Eigen::Vector3d& omega) { return so3_left_jacobian_inverse(-omega); }

Eigen::Isometry3d ImuConfig::T_lidar_imu() const {
  constexpr double kDeg = M_PI / 180.0;
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = (Eigen::AngleAxisd(yaw_deg * kDeg, Eigen::Vector3d::UnitZ()) *
                Eigen::AngleAxisd(pitch_deg * kDeg, Eigen::Vector3d::UnitY()) *
                Eigen::AngleAxisd(roll_deg * kDeg, Eigen::Vector3d::UnitX()))
                   .toRotationMatrix();
  T.translation() = Eigen::Vector3d(x, y, z);
  return T;
}

NavState NavState::retract(const Vector15d& d) const {
  NavState s;
  s.T_world_imu = normalized(T_world_imu * se3_exp(d.head<6>()));
  s.velocity = velocity + d.segment<3>(6);
  s.bias = ImuBias::from_vector(bias.vector() + d.tail<6>());
  return s;
}

ImuPreintegration::ImuPreintegration(const ImuBias& bias_lin, const ImuNoise& noise) : bias_lin_(bias_lin), noise_(noise) {}

// Forster Eq. 37-38 for the deltas, Eq. 62-63 for the covariance, Appendix B for the bias
// Jacobians; every update uses the deltas before this step.
void ImuPreintegration::integrate(const Eigen::Vector3d& gyro, const Eigen::Vector3d& accel, double dt) {
  step(gyro - bias_lin_.gyro, accel - bias_lin_.accel, dt);
}

void ImuPreintegration::step(const Eigen::Vector3d& w, const Eigen::Vector3d& a, double dt) {
  const Eigen::Matrix3d dR_step = so3_exp(w * dt), Jr = so3_right_jacobian(w * dt);
  const Eigen::Matrix3d dR_a = dR_ * skew(a);

  Matrix9d A = Matrix9d::Identity();
  A.block<3, 3>(0, 0) = dR_step.transpose();
  A.block<3, 3>(3, 0) = -dR_a * dt;
  A.block<3, 3>(6, 0) = -0.5 * dR_a * dt * dt;
  A.block<3, 3>(6, 3) = Eigen::Matrix3d::Identity() * dt;
  Eigen::Matrix<double, 9, 3> B = Eigen::Matrix<double, 9, 3>::Zero(), C = Eigen::Matrix<double, 9, 3>::Zero();
  B.topRows<3>() = Jr * dt;
  C.middleRows<3>(3) = dR_ * dt;
  C.bottomRows<3>() = 0.5 * dR_ * dt * dt;
  // Discrete noise of a sample held over dt: density^2 / dt.
  const double sg = noise_.gyro_noise * noise_.gyro_noise / dt, sa = noise_.accel_noise * noise_.accel_noise / dt;
  cov_ = A * cov_ * A.transpose() + sg * B * B.transpose() + sa * C * C.transpose();

  dp_dba_ += dv_dba_ * dt - 0.5 * dR_ * dt * dt;
  dp_dbg_ += dv_dbg_ * dt - 0.5 * dR_a * dR_dbg_ * dt * dt;
  dv_dba_ -= dR_ * dt;
  dv_dbg_ -= dR_a * dR_dbg_ * dt;
  dR_dbg_ = dR_step.transpose() * dR_dbg_ - Jr * dt;

  dp_ += dv_ * dt + 0.5 * dR_ * a * dt * dt;
  dv_ += dR_ * a * dt;
  dR_ = dR_ * dR_step;
  Eigen::Quaterniond q(dR_);  // re-orthonormalized: thousands of products drift
  dR_ = q.normalized().toRotationMatrix();
  dt_ += dt;
}

namespace {
// The signal at time t between two samples.
ImuSample interpolate(const ImuSample& a, const ImuSample& b, double t) {
  const double f = b.stamp > a.stamp ? (t - a.stamp) / (b.stamp - a.stamp) : 0.0;
  return {t, a.gyro + f * (b.gyro - a.gyro), a.accel + f * (b.accel - a.accel)};
}
}  // namespace

void ImuPreintegration::integrate(const std::vector<ImuSample>& samples, double t0, double t1) {
  if (samples.empty() || samples.front().stamp > t0 || samples.back().stamp < t1)
    throw Error("IMU samples do not cover the interval [" + std::to_string(t0) + ", " + std::to_string(t1) + "] s");
  // The last sample at or before t0.
  size_t k = std::upper_bound(samples.begin(), samples.end(), t0, [](double t, const ImuSample& s) { return t < s.stamp; }) -
             samples.begin() - 1;
  ImuSample prev = k + 1 < samples.size() ? interpolate(samples[k], samples[k + 1], t0) : samples[k];
  prev.stamp = t0;
  for (++k; prev.stamp < t1; ++k) {
    if (k < samples.size() && samples[k].stamp < samples[k - 1].stamp)
      throw Error("IMU samples are not in stamp order at stamp " + std::to_string(samples[k].stamp));
    const ImuSample next = k < samples.size() && samples[k].stamp < t1 ? samples[k] : interpolate(samples[k - 1], samples[k], t1);
    const double dt = next.stamp - prev.stamp;
    if (dt > 0) {
      // The mean rate, and the mean of the two accelerations in the step's starting frame (the
      // trapezoid rule in the world): both second order.
      const Eigen::Vector3d w = 0.5 * (prev.gyro + next.gyro) - bias_lin_.gyro;
      step(w, 0.5 * (prev.accel - bias_lin_.accel + so3_exp(w * dt) * (next.accel - bias_lin_.accel)), dt);
    }
    prev = next;
  }
}

Eigen::Matrix3d ImuPreintegration::corrected_delta_R(const ImuBias& bias) const {
  return dR_ * so3_exp(dR_dbg_ * (bias.gyro - bias_lin_.gyro));
}

Eigen::Vector3d ImuPreintegration::corrected_delta_v(const ImuBias& bias) const {
  return dv_ + dv_dbg_ * (bias.gyro - bias_lin_.gyro) + dv_dba_ * (bias.accel - bias_lin_.accel);
}

Eigen::Vector3d ImuPreintegration::corrected_delta_p(const ImuBias& bias) const {
  return dp_ + dp_dbg_ * (bias.gyro - bias_lin_.gyro) + dp_dba_ * (bias.accel - bias_lin_.accel);
}

NavState ImuPreintegration::predict(const NavState& start, const Eigen::Vector3d& gravity) const {
  const Eigen::Matrix3d& R_i = start.T_world_imu.linear();
  const Eigen::Vector3d& p_i = start.T_world_imu.translation();
  NavState end = start;
  end.T_world_imu.linear() = R_i * corrected_delta_R(start.bias);
  end.velocity = start.velocity + gravity * dt_ + R_i * corrected_delta_v(start.bias);
  end.T_world_imu.translation() = p_i + start.velocity * dt_ + 0.5 * gravity * dt_ * dt_ + R_i * corrected_delta_p(start.bias);
  return end;
}

}  // namespace gcmap
