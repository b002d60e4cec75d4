#include "gcmap/odometry/inertial_track.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <memory>

#include "gcmap/core/error.hpp"
#include "gcmap/odometry/odometry.hpp"

namespace gcmap {

namespace {
// Gravity is found from this much registered motion (s), each half of it at least kMinHalf.
constexpr double kInitSpan = 1.0, kMinHalf = 0.3;
// A gravity whose magnitude is this far off is no gravity: the registration erred meanwhile.
constexpr double kGravityTolerance = 0.2;
// What the state is known to at its start: the registration's pose, a velocity from positions
// over half a second, and biases as a MEMS IMU's turn-on spread.
constexpr double kStartRotation = 0.002, kStartPosition = 0.01, kStartVelocity = 0.1, kStartGyroBias = 0.01,
                 kStartAccelBias = 0.2;
// A registration's Hessian counts every point as an independent measurement; neighbouring points
// are not. A quarter of it weighed the registrations of a 64-beam drive and of a handheld
// Mid-360-like sensor both about right against the IMU (docs/benchmarks.md).
constexpr double kHessianScale = 0.25;
}  // namespace

Matrix6d registration_information(const Matrix6d& hessian) {
  const Matrix6d H = 0.5 * (hessian + hessian.transpose());
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(H.bottomRightCorner<3, 3>());
  const double largest = eig.eigenvalues()(2);
  if (!(largest > 0.0)) return Matrix6d::Zero();
  // Translations with less than kDegenerateConditioning of the best one's information are dropped,
  // the others' information multiplied by their share. What a scan hardly constrains is biased,
  // not merely weak: along a tunnel towards the model's last keyframe and towards moving traffic.
  // Kept weak, it would pull the velocity down sweep after sweep.
  Matrix6d W = Matrix6d::Identity();
  W.bottomRightCorner<3, 3>().setZero();
  for (int k = 0; k < 3; ++k) {
    const double share = eig.eigenvalues()(k) / largest;
    if (share >= kDegenerateConditioning)
      W.bottomRightCorner<3, 3>() += std::sqrt(share) * eig.eigenvectors().col(k) * eig.eigenvectors().col(k).transpose();
  }
  return kHessianScale * W * H * W;
}

InertialTrack::InertialTrack(const ImuConfig& config) : config_(config), T_imu_lidar_(config.T_lidar_imu().inverse()) {}

void InertialTrack::add(const ImuSample& sample) {
  ImuSample s = sample;
  s.stamp -= config_.time_offset;
  if (!samples_.empty() && s.stamp <= samples_.back().stamp) return;  // GyroTrack reports disorder
  samples_.push_back(s);
}

bool InertialTrack::covers(double t0, double t1) const {
  return !samples_.empty() && samples_.front().stamp <= t0 && samples_.back().stamp >= t1;
}

std::optional<Eigen::Isometry3d> InertialTrack::predict(double time) const {
  if (!state_ || time < state_time_ || !covers(state_time_, time)) return std::nullopt;
  ImuPreintegration pre(state_->bias, config_.noise);
  pre.integrate(samples_, state_time_, time);
  return normalized(pre.predict(*state_, gravity_).T_world_imu * T_imu_lidar_);
}

void InertialTrack::reset() {
  state_.reset();
  start_.clear();
}

void InertialTrack::observe(double time, const Eigen::Isometry3d& T_world_lidar, const Matrix6d* information) {
  if (state_ && (time <= state_time_ || !covers(state_time_, time))) reset();
  if (state_) {
    update(time, information ? &T_world_lidar : nullptr, information);
  } else if (!information) {
    start_.clear();
  } else {
    start_.push_back({time, T_world_lidar});
    while (start_.size() > 2 && start_[1].stamp <= time - kInitSpan) start_.erase(start_.begin());
    if (time - start_.front().stamp >= kInitSpan && initialize()) start_.clear();
  }
  // Samples before what can still be needed go (in blocks: the vector shifts).
  const double keep = state_ ? state_time_ : (start_.empty() ? time : start_.front().stamp);
  const auto first = std::lower_bound(samples_.begin(), samples_.end(), keep - 0.1,
                                      [](const ImuSample& s, double t) { return s.stamp < t; });
  if (first - samples_.begin() > 1000) samples_.erase(samples_.begin(), first);
}

bool InertialTrack::initialize() {
  const size_t b = start_.size() - 1;
  const double middle = 0.5 * (start_.front().stamp + start_[b].stamp);
  const size_t m = std::min_element(start_.begin(), start_.end(),
                                    [&](const OdometryFrame& x, const OdometryFrame& y) {
                                      return std::abs(x.stamp - middle) < std::abs(y.stamp - middle);
                                    }) -
                   start_.begin();
  const double T2 = start_[b].stamp - start_[m].stamp;
  if (start_[m].stamp - start_.front().stamp < kMinHalf || T2 < kMinHalf) return false;
  const std::optional<GravityWindow> window = gravity_window(samples_, start_, 0, m, b, config_, Eigen::Isometry3d::Identity());
  if (!window) return false;
  const Eigen::Vector3d g = window->gravity(Eigen::Vector3d::Zero());
  if (std::abs(g.norm() - config_.gravity) > kGravityTolerance * config_.gravity) return false;
  gravity_ = g.normalized() * config_.gravity;
  // The velocity over [m, b] from the positions there and what the specific force adds.
  const Eigen::Isometry3d T_lidar_imu = T_imu_lidar_.inverse();
  const auto p = [&](size_t k) { return Eigen::Vector3d(start_[k].T_odom_lidar * T_lidar_imu.translation()); };
  const ForceIntegral mb = integrate_force(samples_, start_, m, b, config_);
  const Eigen::Vector3d v_m = (p(b) - p(m) - 0.5 * gravity_ * T2 * T2 - mb.P) / T2;
  NavState s;
  s.T_world_imu = start_[b].T_odom_lidar * T_lidar_imu;
  s.velocity = v_m + gravity_ * T2 + mb.V;
  state_ = s;
  state_time_ = start_[b].stamp;
  Vector15d sigma;
  sigma << Eigen::Vector3d::Constant(kStartRotation), Eigen::Vector3d::Constant(kStartPosition),
      Eigen::Vector3d::Constant(kStartVelocity), Eigen::Vector3d::Constant(kStartGyroBias), Eigen::Vector3d::Constant(kStartAccelBias);
  information_ = sigma.cwiseInverse().cwiseAbs2().asDiagonal();
  return true;
}

void InertialTrack::update(double time, const Eigen::Isometry3d* T_world_lidar, const Matrix6d* information) {
  ImuPreintegration pre(state_->bias, config_.noise);
  pre.integrate(samples_, state_time_, time);
  std::vector<NavState> states{*state_, pre.predict(*state_, gravity_)};
  std::vector<std::unique_ptr<NavFactor>> factors;
  factors.push_back(std::make_unique<NavPriorFactor>(0, *state_, information_));
  factors.push_back(std::make_unique<BiasRandomWalkFactor>(0, 1, pre.dt(), config_.noise));
  factors.push_back(std::make_unique<ImuFactor>(0, 1, std::move(pre), gravity_));
  if (T_world_lidar) factors.push_back(std::make_unique<LidarPoseFactor>(1, *T_world_lidar, *information, T_imu_lidar_));
  optimize_nav_states(factors, states, 10);
  // The older state marginalized (Schur complement): its information passes to the newer one.
  const Eigen::MatrixXd H = nav_information(factors, states);
  const Matrix15d H_new = H.bottomRightCorner<15, 15>() - H.block<15, 15>(15, 0) * H.topLeftCorner<15, 15>().ldlt().solve(H.block<15, 15>(0, 15));
  information_ = 0.5 * (H_new + H_new.transpose()) + 1e-9 * Matrix15d::Identity();
  state_ = states[1];
  state_time_ = time;
  last_bias_ = state_->bias;
}

}  // namespace gcmap
