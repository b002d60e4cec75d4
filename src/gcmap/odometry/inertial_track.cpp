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
// How far (in sigmas of the registration and the IMU's prediction together) a registered pose may
// stray from the prediction before it counts less.
constexpr double kGate = 5.0;
// Gravity's direction in the odometry frame: known to this at the start (rad, a gravity window over
// a second of registered sweeps) and wandering by this (rad/sqrt(s)) as the odometry's roll and
// pitch do. Walks of 0, 0.001 and 0.003 did alike on the vehicles' drives; 0.001 mapped the
// simulated walks best (docs/benchmarks.md, "Gravity's direction in the state").
constexpr double kStartGravityTilt = 0.02, kGravityWalk = 0.001;

using Matrix17d = Eigen::Matrix<double, 17, 17>;
using Vector17d = Eigen::Matrix<double, 17, 1>;

// Gravity's direction as two angles about axes across a reference gravity.
struct GravityTilt {
  Eigen::Vector3d reference;
  Eigen::Matrix<double, 3, 2> axes;
  explicit GravityTilt(const Eigen::Vector3d& g) : reference(g) {
    const Eigen::Vector3d u = g.normalized();
    const Eigen::Vector3d a = (std::abs(u.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY()).cross(u).normalized();
    axes << a, u.cross(a);
  }
  Eigen::Vector3d at(const Eigen::Vector2d& theta) const { return so3_exp(axes * theta) * reference; }
  Eigen::Matrix<double, 3, 2> jacobian(const Eigen::Vector2d& theta) const { return -skew(at(theta)) * axes; }
};

bool constrains_every_translation(const Matrix6d& information) {
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(information.bottomRightCorner<3, 3>());
  return eig.eigenvalues()(0) > 1e-6 * eig.eigenvalues()(2);
}

// The smoother's window: the older state (0) under its prior, the newer one (1), and gravity's tilt.
// Unknowns ordered [tilt (2), state 0 (15), state 1 (15)].
struct Window {
  std::vector<std::unique_ptr<NavFactor>> factors;  // over the states
  ImuFactor* imu = nullptr;                         // among them: the one gravity enters
  NavState prior;
  Matrix17d prior_information;  // over [tilt, state 0]
  GravityTilt tilt;
  bool tilt_free = true;  // false: the tilt is held at its prior

  // [tilt; state 0 against the prior], unwhitened, and its Jacobian.
  Vector17d prior_residual(const NavState& s0, const Eigen::Vector2d& theta, Matrix17d* J) const {
    const NavPriorFactor f(0, prior, Matrix15d::Identity());
    const NavState* s[2] = {&s0, nullptr};
    const NavLinearization lin = f.linearize(s);
    if (J) J->setIdentity(), J->bottomRightCorner<15, 15>() = lin.J[0];
    return (Vector17d() << theta, lin.r).finished();
  }
  double error(const std::vector<NavState>& states, const Eigen::Vector2d& theta) const {
    imu->set_gravity(tilt.at(theta));
    const Vector17d r = prior_residual(states[0], theta, nullptr);
    return nav_error(factors, states) + r.dot(prior_information * r);
  }
  void system(const std::vector<NavState>& states, const Eigen::Vector2d& theta, Eigen::MatrixXd& H, Eigen::VectorXd& b) const;
  // The system a step solves: a held tilt is no unknown (its rows and columns out, which conditions
  // state 0's prior on it); left in, the prior's correlations would move it with state 0.
  void step_system(const std::vector<NavState>& states, const Eigen::Vector2d& theta, Eigen::MatrixXd& H,
                   Eigen::VectorXd& b) const {
    system(states, theta, H, b);
    if (tilt_free) return;
    H.topRows<2>().setZero();
    H.leftCols<2>().setZero();
    H.topLeftCorner<2, 2>().setIdentity();
    b.head<2>().setZero();
  }
};

void Window::system(const std::vector<NavState>& states, const Eigen::Vector2d& theta, Eigen::MatrixXd& H,
                    Eigen::VectorXd& b) const {
  imu->set_gravity(tilt.at(theta));
  Eigen::MatrixXd H_states;
  Eigen::VectorXd b_states;
  nav_system(factors, states, H_states, b_states);
  H = Eigen::MatrixXd::Zero(32, 32), b = Eigen::VectorXd::Zero(32);
  H.bottomRightCorner<30, 30>() = H_states, b.tail<30>() = b_states;
  const NavState* s[2] = {&states[0], &states[1]};
  const NavLinearization lin = imu->linearize(s);
  const Eigen::Matrix<double, 9, 2> Jg =
      tilt_free ? Eigen::Matrix<double, 9, 2>(imu->gravity_jacobian(states[0]) * tilt.jacobian(theta))
                : Eigen::Matrix<double, 9, 2>::Zero();
  H.topLeftCorner<2, 2>() += Jg.transpose() * Jg;
  H.block<2, 15>(0, 2) += Jg.transpose() * lin.J[0];
  H.block<2, 15>(0, 17) += Jg.transpose() * lin.J[1];
  H.block<30, 2>(2, 0) = H.block<2, 30>(0, 2).transpose();
  b.head<2>() += Jg.transpose() * lin.r;
  Matrix17d J;
  const Vector17d r = prior_residual(states[0], theta, &J);
  H.topLeftCorner<17, 17>() += J.transpose() * prior_information * J;
  b.head<17>() += J.transpose() * prior_information * r;
}

// A registration the IMU's prediction contradicts (its pitch slid with its model, or it fell
// metres short along a canyon) counts less, down to nothing: above kGate its information is
// scaled by kGate^2 / chi2, where chi2 weighs its disagreement with the prediction by the two
// covariances together (the prediction's from the window without the registration).
double registration_weight(const Window& w, const std::vector<NavState>& states, const Eigen::Isometry3d& T_world_lidar,
                           const Matrix6d& information, const Eigen::Isometry3d& T_imu_lidar) {
  Eigen::MatrixXd H;
  Eigen::VectorXd b;
  w.step_system(states, Eigen::Vector2d::Zero(), H, b);
  // The covariance of state 1's pose (after the tilt (2) and state 0 (15)): its six columns only.
  const Eigen::MatrixXd columns = H.ldlt().solve(Eigen::MatrixXd::Identity(H.rows(), H.cols()).middleCols<6>(17));
  const Matrix6d A = adjoint(T_imu_lidar.inverse());  // IMU pose tangent to the LiDAR's
  const Matrix6d P = A * columns.middleRows<6>(17) * A.transpose();
  const Vector6d r = pose_difference(T_world_lidar, states[1].T_world_imu * T_imu_lidar);
  // (P + information^-1)^-1 without inverting the information, which may be singular.
  const Matrix6d S_inv = information - information * (P.inverse() + information).ldlt().solve(information);
  const double chi2 = r.dot(S_inv * r);
  return chi2 > kGate * kGate ? kGate * kGate / chi2 : 1.0;
}

// Levenberg-Marquardt over the window's states and tilt.
void optimize(const Window& w, std::vector<NavState>& states, Eigen::Vector2d& theta, int max_iterations) {
  std::vector<NavState> moved(2);
  Eigen::Vector2d moved_theta;
  dense_levenberg_marquardt(
      w.error(states, theta), max_iterations, [&](Eigen::MatrixXd& H, Eigen::VectorXd& b) { w.step_system(states, theta, H, b); },
      [&](const Eigen::VectorXd& d) {
        moved = {states[0].retract(d.segment<15>(2)), states[1].retract(d.tail<15>())};
        moved_theta = theta + d.head<2>();
        return w.error(moved, moved_theta);
      },
      [&] {
        states.swap(moved);
        theta = moved_theta;
      });
}

// The information over [tilt, state 1] once state 0 is marginalized (Schur complement), the tilt
// then left to wander for dt seconds (its covariance grows by walk^2 dt: Woodbury, 2x2).
Matrix17d marginalized(const Eigen::MatrixXd& H, double dt, bool walk) {
  std::vector<int> keep{0, 1}, drop;
  for (int k = 2; k < 17; ++k) drop.push_back(k);
  for (int k = 17; k < 32; ++k) keep.push_back(k);
  const Eigen::MatrixXd Hkk = H(keep, keep), Hkd = H(keep, drop), Hdd = H(drop, drop);
  Matrix17d L = Hkk - Hkd * Hdd.ldlt().solve(Hkd.transpose());
  L = 0.5 * (L + L.transpose()) + 1e-9 * Matrix17d::Identity();
  const double q = walk ? kGravityWalk * kGravityWalk * dt : 0.0;
  if (q > 0.0) {
    const Eigen::Matrix<double, 17, 2> LE = L.leftCols<2>();
    const Eigen::Matrix2d inner = Eigen::Matrix2d::Identity() / q + L.topLeftCorner<2, 2>();
    L -= LE * inner.ldlt().solve(LE.transpose());
    L = 0.5 * (L + L.transpose());
  }
  return L;
}
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
  const auto first =
      std::lower_bound(samples_.begin(), samples_.end(), keep - 0.1, [](const ImuSample& s, double t) { return s.stamp < t; });
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
  gravity_ = start_gravity_ = g.normalized() * config_.gravity;
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
  Vector17d sigma;
  sigma << Eigen::Vector2d::Constant(kStartGravityTilt), Eigen::Vector3d::Constant(kStartRotation),
      Eigen::Vector3d::Constant(kStartPosition), Eigen::Vector3d::Constant(kStartVelocity),
      Eigen::Vector3d::Constant(kStartGyroBias), Eigen::Vector3d::Constant(kStartAccelBias);
  information_ = sigma.cwiseInverse().cwiseAbs2().asDiagonal();
  return true;
}

void InertialTrack::update(double time, const Eigen::Isometry3d* T_world_lidar, const Matrix6d* information) {
  ImuPreintegration pre(state_->bias, config_.noise);
  pre.integrate(samples_, state_time_, time);
  const double dt = pre.dt();
  std::vector<NavState> states{*state_, pre.predict(*state_, gravity_)};
  // Where the registration leaves a translation unknown (a tunnel's axis), a tilt of gravity along
  // it is a forward acceleration: the tilt is held.
  const bool tilt_free = T_world_lidar && constrains_every_translation(*information);
  Window w{{}, nullptr, *state_, information_, GravityTilt(gravity_), tilt_free};
  w.factors.push_back(std::make_unique<BiasRandomWalkFactor>(0, 1, dt, config_.noise));
  auto imu = std::make_unique<ImuFactor>(0, 1, std::move(pre), gravity_);
  w.imu = imu.get();
  w.factors.push_back(std::move(imu));
  if (T_world_lidar) {
    const double weight = registration_weight(w, states, *T_world_lidar, *information, T_imu_lidar_);
    w.factors.push_back(std::make_unique<LidarPoseFactor>(1, *T_world_lidar, weight * *information, T_imu_lidar_));
  }
  Eigen::Vector2d theta = Eigen::Vector2d::Zero();
  optimize(w, states, theta, 10);
  Eigen::MatrixXd H;
  Eigen::VectorXd b;
  w.system(states, theta, H, b);
  information_ = marginalized(H, dt, tilt_free);
  gravity_ = w.tilt.at(theta);
  state_ = states[1];
  state_time_ = time;
  last_bias_ = state_->bias;
  last_gravity_turn_deg_ =
      std::acos(std::clamp(gravity_.normalized().dot(start_gravity_.normalized()), -1.0, 1.0)) * 180.0 / M_PI;
}

}  // namespace gcmap
