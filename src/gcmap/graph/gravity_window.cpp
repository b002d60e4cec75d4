#include "gcmap/graph/gravity_window.hpp"

#include <cmath>

namespace gcmap {

namespace {
// The error of an odometry position relative to another a few seconds away (m).
constexpr double kPositionSigma = 0.01;
// s: each half of a window at least this long; shorter, position errors swamp gravity.
constexpr double kMinInterval = 0.2;

bool covers(const std::vector<ImuSample>& samples, double t0, double t1) {
  return !samples.empty() && samples.front().stamp <= t0 && samples.back().stamp >= t1;
}

}  // namespace

ForceIntegral integrate_force(const std::vector<ImuSample>& samples, const std::vector<OdometryFrame>& frames, size_t i0,
                              size_t i1, const ImuConfig& imu) {
  const Eigen::Matrix3d R_lidar_imu = imu.T_lidar_imu().linear();
  ForceIntegral f;
  for (size_t k = i0; k < i1; ++k) {
    ImuPreintegration pre({}, imu.noise);
    pre.integrate(samples, frames[k].stamp, frames[k + 1].stamp);
    const Eigen::Matrix3d R = frames[k].T_odom_lidar.linear() * R_lidar_imu;
    const double dt = pre.dt();
    f.P += f.V * dt + R * pre.delta_p();
    f.dP += f.dV * dt + R * pre.dp_dba();
    f.V += R * pre.delta_v();
    f.dV += R * pre.dv_dba();
  }
  return f;
}

std::optional<GravityWindow> gravity_window(const std::vector<ImuSample>& samples, const std::vector<OdometryFrame>& frames,
                                            size_t a, size_t m, size_t b, const ImuConfig& imu,
                                            const Eigen::Isometry3d& T_odom_submap) {
  if (!(a < m && m < b && b < frames.size())) return std::nullopt;
  if (!covers(samples, frames[a].stamp, frames[b].stamp)) return std::nullopt;
  const Eigen::Vector3d t_lidar_imu = imu.T_lidar_imu().translation();
  const auto p = [&](size_t k) { return Eigen::Vector3d(frames[k].T_odom_lidar * t_lidar_imu); };
  const double T1 = frames[m].stamp - frames[a].stamp, T2 = frames[b].stamp - frames[m].stamp;
  if (!(T1 >= kMinInterval && T2 >= kMinInterval)) return std::nullopt;  // repeated stamps, or too short to tell
  const ForceIntegral am = integrate_force(samples, frames, a, m, imu), mb = integrate_force(samples, frames, m, b, imu);
  const Eigen::Vector3d c = (p(b) - p(m)) / T2 - (p(m) - p(a)) / T1 + am.P / T1 - am.V - mb.P / T2;
  const Eigen::Matrix3d M = -(am.dP / T1 - am.dV - mb.dP / T2);
  GravityWindow w;
  const Eigen::Matrix3d R_submap_odom = T_odom_submap.linear().transpose();
  w.c = R_submap_odom * c;
  w.M = R_submap_odom * M;
  w.duration = 0.5 * (T1 + T2);
  // Three independent position errors through the formula, and the accelerometer's white noise
  // over the window.
  const double position = kPositionSigma * std::sqrt(1.0 / (T1 * T1) + std::pow(1.0 / T1 + 1.0 / T2, 2) + 1.0 / (T2 * T2));
  const double accel = imu.noise.accel_noise * std::sqrt(w.duration);
  w.sigma = std::hypot(position, accel) / (imu.gravity * w.duration);
  return w;
}

}  // namespace gcmap
