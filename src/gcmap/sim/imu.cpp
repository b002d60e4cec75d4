#include "gcmap/sim/imu.hpp"

#include <algorithm>
#include <array>
#include <cmath>

#include "gcmap/core/error.hpp"
#include "gcmap/sim/rng.hpp"
#include "gcmap/sim/simulator.hpp"

namespace gcmap::sim {

namespace {

// A polynomial sum_i c[i] tau^i and its first two derivatives at tau.
template <size_t N>
Eigen::Vector3d poly(const std::array<double, N>& c, double tau) {
  Eigen::Vector3d out = Eigen::Vector3d::Zero();  // value, d/dtau, d2/dtau2
  for (size_t i = 0; i < N; ++i) {
    out[0] += c[i] * std::pow(tau, double(i));
    if (i >= 1) out[1] += c[i] * double(i) * std::pow(tau, double(i - 1));
    if (i >= 2) out[2] += c[i] * double(i * (i - 1)) * std::pow(tau, double(i - 2));
  }
  return out;
}

// Quintic Hermite basis: p0, v0, a0, a1, v1, p1.
constexpr std::array<std::array<double, 6>, 6> kQuintic{{{1, 0, 0, -10, 15, -6},
                                                         {0, 1, 0, -6, 8, -3},
                                                         {0, 0, 0.5, -1.5, 1.5, -0.5},
                                                         {0, 0, 0, 0.5, -1, 0.5},
                                                         {0, 0, 0, -4, 7, -3},
                                                         {0, 0, 0, 10, -15, 6}}};
// Cubic Hermite basis without the start value (phi(0) = 0): m0, p1, m1.
constexpr std::array<std::array<double, 4>, 3> kCubic{{{0, 1, -2, 1}, {0, 0, 3, -2}, {0, 0, -1, 1}}};

}  // namespace

Eigen::Isometry3d ImuSimConfig::default_T_lidar_imu() {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Eigen::Vector3d(0.0417, 0.0233, -0.0284);
  return T;
}

ImuTrajectory::ImuTrajectory(const std::vector<Eigen::Isometry3d>& T_world_lidar, double period,
                             const Eigen::Isometry3d& T_lidar_imu)
    : period_(period) {
  const size_t n = T_world_lidar.size();
  if (n < 2) throw Error("a simulated IMU needs at least 2 frames");
  for (const auto& T : T_world_lidar) {
    const Eigen::Isometry3d T_world_imu = T * T_lidar_imu;
    R_.push_back(T_world_imu.linear());
    p_.push_back(T_world_imu.translation());
  }
  const double h = period;
  std::vector<Eigen::Vector3d> step(n - 1);  // log(R_k^T R_k+1)
  for (size_t k = 0; k + 1 < n; ++k) step[k] = so3_log(R_[k].transpose() * R_[k + 1]);
  for (size_t k = 0; k < n; ++k) {
    const size_t a = k > 0 ? k - 1 : 0, b = std::min(k + 1, n - 1);
    v_.push_back((p_[b] - p_[a]) / (h * double(b - a)));
    a_.push_back(k > 0 && k + 1 < n ? Eigen::Vector3d((p_[b] - 2.0 * p_[k] + p_[a]) / (h * h)) : Eigen::Vector3d::Zero());
    const Eigen::Vector3d before = k > 0 ? step[k - 1] : step[k], after = k + 1 < n ? step[k] : step[k - 1];
    w_.push_back((before + after) / (2.0 * h));
  }
  for (size_t k = 0; k + 1 < n; ++k) {
    phi_end_.push_back(step[k]);
    dphi_end_.push_back(h * so3_right_jacobian_inverse(step[k]) * w_[k + 1]);
  }
}

std::pair<size_t, double> ImuTrajectory::locate(double t) const {
  const double f = t / period_;
  const size_t k = std::min<size_t>(static_cast<size_t>(std::max(std::floor(f), 0.0)), R_.size() - 2);
  return {k, f - double(k)};
}

NavState ImuTrajectory::state(double t) const {
  const auto [k, tau] = locate(t);
  const double h = period_;
  const std::array<Eigen::Vector3d, 6> P{p_[k], h * v_[k], h * h * a_[k], h * h * a_[k + 1], h * v_[k + 1], p_[k + 1]};
  const std::array<Eigen::Vector3d, 3> Phi{h * w_[k], phi_end_[k], dphi_end_[k]};
  NavState s;
  Eigen::Vector3d p = Eigen::Vector3d::Zero(), v = Eigen::Vector3d::Zero(), phi = Eigen::Vector3d::Zero();
  for (int i = 0; i < 6; ++i) {
    const Eigen::Vector3d b = poly(kQuintic[i], tau);
    p += b[0] * P[i], v += b[1] * P[i];
  }
  for (int i = 0; i < 3; ++i) phi += poly(kCubic[i], tau)[0] * Phi[i];
  s.T_world_imu.linear() = R_[k] * so3_exp(phi);
  s.T_world_imu.translation() = p;
  s.velocity = v / h;
  return s;
}

ImuSample ImuTrajectory::measure(double t) const {
  const auto [k, tau] = locate(t);
  const double h = period_;
  const std::array<Eigen::Vector3d, 6> P{p_[k], h * v_[k], h * h * a_[k], h * h * a_[k + 1], h * v_[k + 1], p_[k + 1]};
  const std::array<Eigen::Vector3d, 3> Phi{h * w_[k], phi_end_[k], dphi_end_[k]};
  Eigen::Vector3d acc = Eigen::Vector3d::Zero(), phi = Eigen::Vector3d::Zero(), dphi = Eigen::Vector3d::Zero();
  for (int i = 0; i < 6; ++i) acc += poly(kQuintic[i], tau)[2] * P[i];
  for (int i = 0; i < 3; ++i) {
    const Eigen::Vector3d b = poly(kCubic[i], tau);
    phi += b[0] * Phi[i], dphi += b[1] * Phi[i];
  }
  const Eigen::Matrix3d R = R_[k] * so3_exp(phi);
  return {t, so3_right_jacobian(phi) * dphi / h, R.transpose() * (acc / (h * h) - gravity_vector())};
}

ImuTrajectory imu_trajectory(const Simulator& sim, const Eigen::Isometry3d& T_lidar_imu) {
  constexpr int kKnotsPerFrame = 10;
  const double step = 0.1 / kKnotsPerFrame;
  std::vector<Eigen::Isometry3d> knots;
  for (size_t i = 0; i <= (sim.num_frames() - 1) * kKnotsPerFrame; ++i) knots.push_back(sim.pose_at_time(step * double(i)));
  return ImuTrajectory(knots, step, T_lidar_imu);
}

SimulatedImu simulate_imu(const ImuTrajectory& trajectory, const ImuSimConfig& config, uint64_t seed) {
  if (!(config.rate > 0)) throw Error("--imu-rate: must be positive");
  const double dt = 1.0 / config.rate;
  const size_t n = static_cast<size_t>(std::floor(trajectory.duration() * config.rate + 1e-9)) + 1;
  Rng rng(hash_key(seed, 0x1A0));
  const auto normal3 = [&] { return Eigen::Vector3d(rng.normal(), rng.normal(), rng.normal()); };
  const ImuNoise& d = config.density;
  // Initial biases of a MEMS IMU after its factory calibration.
  ImuSample bias{0.0, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()};
  if (config.noise) bias.gyro = 2e-3 * normal3(), bias.accel = 5e-2 * normal3();
  SimulatedImu out;
  for (size_t j = 0; j < n; ++j) {
    const double t = double(j) / config.rate;
    ImuSample s = trajectory.measure(t);
    s.stamp = t + config.time_offset;
    bias.stamp = s.stamp;
    if (config.noise) {
      s.gyro += bias.gyro + d.gyro_noise / std::sqrt(dt) * normal3();
      s.accel += bias.accel + d.accel_noise / std::sqrt(dt) * normal3();
    }
    out.samples.push_back(s);
    out.bias.push_back(bias);
    if (config.noise)
      bias.gyro += d.gyro_bias_walk * std::sqrt(dt) * normal3(), bias.accel += d.accel_bias_walk * std::sqrt(dt) * normal3();
  }
  return out;
}

}  // namespace gcmap::sim
