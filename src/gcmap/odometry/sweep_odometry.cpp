#include "gcmap/odometry/sweep_odometry.hpp"

#include <algorithm>
#include <cmath>

#include "gcmap/core/deskew.hpp"
#include "gcmap/core/se3.hpp"

namespace gcmap {

namespace {

// How far the gyro's bias estimates may be off (rad/s): the gyro's own, a low-pass of the
// registered rotations, and the LiDAR-inertial state's.
constexpr double kGyroBiasError = 2e-3, kInertialGyroBiasError = 3e-4;
// Registered rotation rates that miss the gyro's by this many times its configured noise: the
// registration is the noisier (a sensor in hand), and the LiDAR-inertial state's motion deskews.
constexpr double kNoisierRegistration = 2.0;

double mean_time(const PointCloud& cloud) {
  double sum = 0.0;
  for (const float t : cloud.times) sum += t;
  return sum / static_cast<double>(cloud.size());
}

double mean_shift(const PointCloud& before, const PointCloud& after) {
  double sum = 0.0;
  for (size_t i = 0; i < before.size(); ++i) sum += (after.points[i] - before.points[i]).norm();
  return before.empty() ? 0.0 : sum / static_cast<double>(before.size());
}

}  // namespace

SweepOdometry::SweepOdometry(const OdometryConfig& config, const PreprocessConfig& preprocess, const ImuConfig& imu,
                             std::shared_ptr<LinearizationBackend> backend)
    : config_(config),
      backend_(std::move(backend)),
      deskew_(preprocess.deskew),
      redeskew_(preprocess.redeskew),
      odometry_(config_, backend_),
      use_imu_(imu.use),
      gyro_noise_(imu.noise.gyro_noise),
      gyro_(imu),
      inertial_enabled_(imu.use && imu.inertial_odometry),
      inertial_(imu) {}

void SweepOdometry::add_imu(const ImuSample& sample) {
  if (!use_imu_) return;
  gyro_.add(sample);
  if (inertial_enabled_) inertial_.add(sample);
}

std::optional<GyroRotation> SweepOdometry::gyro_rotation(double t0, double t1) const {
  if (!use_imu_ || gyro_rejected_at_ || !(t1 > t0) || !gyro_.covers(t0, t1)) return std::nullopt;
  const double dt = t1 - t0;
  // The LiDAR-inertial state's bias is the better estimate where there is one: the gyro's own is a
  // low-pass of the registered rotations.
  const bool inertial = inertial_enabled_ && inertial_.ready();
  const Eigen::Matrix3d R =
      inertial ? gyro_.rotation(t0, t1, inertial_.T_imu_lidar().linear().transpose() * inertial_.state().bias.gyro)
               : gyro_.rotation(t0, t1);
  const double bias_error = inertial ? kInertialGyroBiasError : kGyroBiasError;
  return GyroRotation{R, gyro_noise_ * gyro_noise_ * dt + std::pow(bias_error * dt, 2)};
}

double SweepOdometry::deskew_gyro_noise() const {
  // The measurement carries the registration's error and wanders as the drive goes on: near
  // imu.gyro_noise it is no reason to leave the configured density.
  constexpr double kClearlyBelow = 0.8;
  const std::optional<double> measured = gyro_.measured_noise();
  return measured && *measured < kClearlyBelow * gyro_noise_ ? *measured : gyro_noise_;
}

bool SweepOdometry::registration_noisier() const {
  const std::optional<double> measured = gyro_.measured_noise();
  return measured && *measured > kNoisierRegistration * gyro_noise_;
}

std::optional<Eigen::Isometry3d> SweepOdometry::inertial_guess(double stamp) const {
  if (!inertial_enabled_ || gyro_rejected_at_) return std::nullopt;
  return inertial_.predict(stamp);
}

std::optional<Eigen::Isometry3d> SweepOdometry::observe_inertial(const SweepEstimate& e, const SweepReference& reference) {
  if (!inertial_enabled_) return std::nullopt;
  if (gyro_rejected_at_) {
    inertial_.reset();
    return std::nullopt;
  }
  const bool registered = e.quality.registered && !e.failed;
  const Matrix6d information = registered ? registration_information(e.quality.hessian) : Matrix6d::Zero();
  const bool ready = inertial_.ready();
  inertial_.observe(reference.stamp, reference.pose, registered ? &information : nullptr);
  if (!ready || !inertial_.ready()) return std::nullopt;
  return normalized(inertial_.state().T_world_imu * inertial_.T_imu_lidar());
}

std::shared_ptr<const SweepOdometry::GyroSweep> SweepOdometry::gyro_sweep(const PointCloud& cloud, double stamp) const {
  if (gyro_rejected_at_) return nullptr;
  const auto [lo, hi] = std::minmax_element(cloud.times.begin(), cloud.times.end());
  const double first = std::min(0.0, static_cast<double>(*lo)), last = std::max(0.0, static_cast<double>(*hi));
  if (!last_ || !gyro_.covers(std::min(last_->second, stamp + first), stamp + last)) return nullptr;
  auto g = std::make_shared<GyroSweep>();
  // A grid through the stamp (t = 0), so that R_stamp_stamp is exactly the identity.
  const long before = static_cast<long>(std::ceil(-first / g->step)), after = static_cast<long>(std::ceil(last / g->step));
  g->t0 = -static_cast<double>(before) * g->step;
  g->R = gyro_.rotations(stamp + g->t0, g->step, static_cast<size_t>(before + after + 1));
  const Eigen::Matrix3d R_stamp_t0 = g->R[static_cast<size_t>(before)].transpose();
  for (Eigen::Matrix3d& R : g->R) R = R_stamp_t0 * R;
  return g;
}

SweepPoses SweepOdometry::SweepMotion::poses() const {
  SweepPoses out;
  out.t0 = gyro->t0, out.step = gyro->step;
  out.T.resize(gyro->R.size(), Eigen::Isometry3d::Identity());
  const size_t zero = static_cast<size_t>(std::lround(-gyro->t0 / gyro->step));
  // The body-frame linear velocity at time t, carried along by the gyro's rotation.
  const auto v = [&](double t) -> Eigen::Vector3d { return velocity.tail<3>() + (t - anchor) * acceleration.tail<3>(); };
  const auto t_of = [&](size_t k) { return gyro->t0 + gyro->step * static_cast<double>(k); };
  const std::vector<Eigen::Vector3d> d = gyro_deviation();
  for (size_t k = 0; k < out.T.size(); ++k) out.T[k].linear() = T_stamp_model(t_of(k)).linear() * so3_exp(gyro_weight * d[k]);
  for (size_t k = zero + 1; k < out.T.size(); ++k)
    out.T[k].translation() =
        out.T[k - 1].translation() + 0.5 * gyro->step * (out.T[k - 1].linear() * v(t_of(k - 1)) + out.T[k].linear() * v(t_of(k)));
  for (size_t k = zero; k-- > 0;)
    out.T[k].translation() =
        out.T[k + 1].translation() - 0.5 * gyro->step * (out.T[k + 1].linear() * v(t_of(k + 1)) + out.T[k].linear() * v(t_of(k)));
  return out;
}

std::vector<Eigen::Vector3d> SweepOdometry::SweepMotion::gyro_deviation() const {
  std::vector<Eigen::Vector3d> d(gyro->R.size());
  for (size_t k = 0; k < d.size(); ++k) {
    const double t = gyro->t0 + gyro->step * static_cast<double>(k);
    d[k] = so3_log(T_stamp_model(t).linear().transpose() * gyro->R[k] * so3_exp(t * gyro_correction));
  }
  return d;
}

void SweepOdometry::SweepMotion::weigh_gyro(double gyro_noise) {
  double signal = 0.0, noise = 0.0;
  const std::vector<Eigen::Vector3d> d = gyro_deviation();
  for (size_t k = 0; k < d.size(); ++k) {
    signal += d[k].squaredNorm();
    // Three axes of a random walk from the stamp.
    noise += 3.0 * gyro_noise * gyro_noise * std::abs(gyro->t0 + gyro->step * static_cast<double>(k));
  }
  gyro_weight = signal > noise ? (signal - noise) / signal : 0.0;
}

void SweepOdometry::SweepMotion::deskew(PointCloud& cloud) const {
  if (gyro) gcmap::deskew(cloud, poses());
  else gcmap::deskew(cloud, velocity, acceleration, anchor);
}

Eigen::Vector3d SweepOdometry::gyro_correction(const Eigen::Isometry3d& T_world_mean, double time) const {
  const double span = time - reference_.stamp;
  if (span < 0.025 || !gyro_.covers(reference_.stamp, time)) return Eigen::Vector3d::Zero();
  const Eigen::Matrix3d R_registered = reference_.pose.linear().transpose() * T_world_mean.linear();
  return so3_log(gyro_.rotation(reference_.stamp, time).transpose() * R_registered) / span;
}

void SweepOdometry::observe_gyro(const SweepReference& reference) {
  // Over about a second the registration's error is small against the bias's integral.
  constexpr double kWindow = 1.0;
  if (!gyro_references_.empty()) {
    const SweepReference& last = gyro_references_.back();
    const double span = reference.stamp - last.stamp;
    if (span > 0.025)
      gyro_.compare_rate(last.stamp, reference.stamp, so3_log(last.pose.linear().transpose() * reference.pose.linear()) / span);
    if (gyro_.disagrees()) gyro_rejected_at_ = frames_;
  }
  gyro_references_.push_back(reference);
  while (gyro_references_.size() > 2 && gyro_references_[1].stamp <= reference.stamp - kWindow) gyro_references_.pop_front();
  const SweepReference& from = gyro_references_.front();
  if (reference.stamp - from.stamp >= 0.5 * kWindow)
    gyro_.observe(from.stamp, from.pose.linear(), reference.stamp, reference.pose.linear());
  gyro_.forget_before(from.stamp - kWindow);
}

SweepEstimate SweepOdometry::track(const std::shared_ptr<PointCloud>& cloud, double stamp,
                                   const std::optional<Eigen::Isometry3d>& T_odom) {
  const double dt = last_ ? stamp - last_->second : 0.0;
  // After a gap of over odometry.max_gap the motion is unknown, as for the first frame.
  const bool timed = cloud && cloud->has_times() && deskew_ && dt > 1e-6 && dt <= config_.max_gap;
  SweepEstimate e;
  if (T_odom) {
    if (timed) {
      deskew(*cloud, se3_log(last_->first.inverse() * *T_odom) / dt);
      e.deskewed = true;
    }
    odometry_.set_pose(*T_odom, stamp);
    reference_ = {*T_odom, stamp};
    inertial_.reset();
    e.T_world_frame = *T_odom;
  } else if (!timed || !odometry_.has_model() || cloud->size() < 100 || !cloud->has_covs()) {
    const bool starts_model = !odometry_.has_model();
    const std::optional<Eigen::Isometry3d> guess = inertial_guess(stamp);
    if (guess && !starts_model && cloud && cloud->size() >= 100 && cloud->has_covs())
      return finish(track_fused(cloud, stamp, *guess), stamp);
    e.T_world_frame = odometry_.track(cloud, stamp, nullptr, guess);
    e.inertial = guess.has_value();
    e.failed = odometry_.last_failed();
    e.quality = odometry_.last_quality();
    reference_ = {e.T_world_frame, stamp};
    observe_inertial(e, reference_);
    if (starts_model && odometry_.has_model() && deskew_ && cloud->has_times())
      first_ = FirstSweep{*cloud, stamp, e.T_world_frame, frames_};
  } else {
    e = track_deskewed(cloud, stamp, dt);
  }
  if (T_odom) previous_mean_.reset(), before_previous_.reset(), previous_.reset(), gyro_references_.clear();
  return finish(std::move(e), stamp);
}

SweepEstimate SweepOdometry::finish(SweepEstimate e, double stamp) {
  if (!e.deskewed) previous_mean_.reset(), before_previous_.reset(), previous_.reset(), gyro_references_.clear();
  if (first_ && frames_ > first_->frame) first_.reset();  // only the next frame restarts
  e.lost = e.failed && !odometry_.has_model();
  last_.emplace(e.T_world_frame, stamp);
  ++frames_;
  return e;
}

SweepEstimate SweepOdometry::track_fused(const std::shared_ptr<PointCloud>& cloud, double stamp, const Eigen::Isometry3d& guess) {
  SweepEstimate e;
  e.inertial = true;
  Eigen::Isometry3d T = odometry_.estimate(*cloud, guess, Odometry::Guess::steady, &e.failed, &e.quality);
  // The scan's pose is taken at its stamp: without point times nothing tells a mean time.
  if (const auto fused = observe_inertial(e, {T, stamp})) T = *fused;
  odometry_.accept(cloud, T, stamp, e.failed, e.quality, true);
  reference_ = {T, stamp};
  e.T_world_frame = T;
  return e;
}

std::shared_ptr<const PointCloud> SweepOdometry::restart_from_first(const Vector6d& velocity) {
  auto first = std::make_shared<PointCloud>(first_->raw);
  deskew(*first, velocity);
  odometry_ = Odometry(config_, backend_);
  odometry_.accept(first, first_->T, first_->stamp);
  const double t_mean = mean_time(*first);
  reference_ = {first_->T * se3_exp(t_mean * velocity), first_->stamp + t_mean};
  SweepMotion motion;
  motion.velocity = velocity;
  previous_ = Revisable{reference_, std::move(first_->raw), first, first_->stamp, first_->frame, motion, first_->T};
  return first;
}

std::optional<SweepRevision> SweepOdometry::revise_previous(const SweepReference& next) {
  if (!redeskew_ || !before_previous_ || !previous_) return std::nullopt;
  const Revisable& p = *previous_;
  // The quadratic x(u) = u v + u^2/2 a in the tangent space at the previous sweep's registered
  // pose (u = 0), through the sweeps before (u0) and after (u2) it.
  const double u0 = before_previous_->stamp - p.reference.stamp, u2 = next.stamp - p.reference.stamp;
  if (u0 > -0.025 || u2 < 0.025) return std::nullopt;  // too close: it would amplify their noise
  const Eigen::Isometry3d T_mean_world = p.reference.pose.inverse();
  const Vector6d x0 = se3_log(T_mean_world * before_previous_->pose), x2 = se3_log(T_mean_world * next.pose);
  const double det = 0.5 * u0 * u2 * (u2 - u0);
  SweepMotion m;
  m.velocity = (0.5 * u2 * u2 * x0 - 0.5 * u0 * u0 * x2) / det;
  m.acceleration = (u0 * x2 - u2 * x0) / det;
  m.anchor = p.reference.stamp - p.stamp;
  const Eigen::Isometry3d T_world_frame = p.reference.pose * m.T_anchor(0.0);
  // A revision that moves no point at 50 m by a centimetre is left out: below that it only adds
  // registration noise and costs a keyframe rebuild.
  double shift = 0.0;
  const float last = *std::max_element(p.raw.times.begin(), p.raw.times.end());
  for (const double t : {0.0, m.anchor, static_cast<double>(last)}) {
    const Eigen::Isometry3d D = (p.T_world_frame * p.motion.T_stamp(t)).inverse() * T_world_frame * m.T_stamp(t);
    shift = std::max(shift, D.translation().norm() + 50.0 * rotation_angle(D));
  }
  if (shift < 0.01) return std::nullopt;
  m.gyro = p.motion.gyro, m.gyro_correction = p.motion.gyro_correction;
  if (m.gyro) m.weigh_gyro(deskew_gyro_noise());
  auto cloud = std::make_shared<PointCloud>(p.raw);
  m.deskew(*cloud);
  // The frame's pose moves onto the curve as well: the keyframe's starting point in the local
  // optimization (kept at the pose it was tracked at, the drive came out less accurate).
  const SweepRevision r{p.frame, cloud, T_world_frame};
  odometry_.revise_keyframe(*p.cloud, cloud, r.T_world_frame);
  return r;
}

SweepEstimate SweepOdometry::track_deskewed(const std::shared_ptr<PointCloud>& cloud, double stamp, double dt) {
  // A deskewed sweep registers best at the mean time of its points: an error of the assumed motion
  // moves earlier and later points in opposite directions. The motion between these instants of
  // the previous and this sweep is the mean velocity there; with the previous sweep's, it gives the
  // acceleration over the sweep (more accurate than a constant velocity at speed, docs/pipeline.md).
  // First the prediction, then that registered motion, refined twice.
  PointCloud raw = *cloud;
  const double t_mean = mean_time(raw);
  SweepEstimate e;
  const std::optional<Eigen::Isometry3d> inertial = inertial_guess(stamp);
  Eigen::Isometry3d T = inertial ? *inertial : odometry_.predict(stamp);
  const Odometry::Guess kind = inertial ? Odometry::Guess::steady : odometry_.guess_kind(stamp);
  const std::shared_ptr<const GyroSweep> gyro = gyro_sweep(raw, stamp);
  if (gyro && !inertial) T.linear() = last_->first.linear() * gyro_.rotation(last_->second, stamp);
  MeanVelocity mean{se3_log(last_->first.inverse() * T) / dt, stamp - 0.5 * dt};
  e.inertial_motion = inertial && registration_noisier();
  SweepMotion m = sweep_motion(mean, stamp, gyro);
  for (int pass = 0; pass < 4; ++pass) {
    *cloud = raw;
    m.deskew(*cloud);
    const Eigen::Isometry3d T_world_stamp =
        odometry_.estimate(*cloud, T, pass == 0 ? kind : Odometry::Guess::steady, &e.failed, &e.quality);
    if (pass == 0 && kind == Odometry::Guess::rest) {
      // Registered undeskewed: only a first velocity, between the stamps.
      mean.velocity = se3_log(last_->first.inverse() * T_world_stamp) / dt;
      m = sweep_motion(mean, stamp, gyro);
      T = T_world_stamp;
      if (first_ && !e.failed) e.revised = SweepRevision{first_->frame, restart_from_first(mean.velocity), first_->T};
      continue;
    }
    const Eigen::Isometry3d T_world_mean = T_world_stamp * m.T_stamp(t_mean);
    const bool degenerate = e.quality.conditioning() < kDegenerateConditioning;
    // Registrations noisier than the IMU (a sensor in hand) leave the state's motion in place.
    const std::optional<MeanVelocity> registered =
        e.inertial_motion ? std::nullopt : registered_mean(T_world_mean, stamp + t_mean, degenerate);
    if (registered) mean = *registered;
    m = sweep_motion(mean, stamp, gyro);
    if (gyro) m.gyro_correction = gyro_correction(T_world_mean, stamp + t_mean), m.weigh_gyro(deskew_gyro_noise());
    T = T_world_mean * m.T_stamp(t_mean).inverse();
  }
  // The gyro's rotations compose with the last pose's; through a run of failures nothing registered
  // re-orthonormalizes them.
  if (gyro) T = normalized(T);
  if (const auto fused = observe_inertial(e, {T * m.T_stamp(t_mean), stamp + t_mean})) T = *fused * m.T_stamp(t_mean).inverse();
  *cloud = raw;
  m.deskew(*cloud);
  e.deskew_shift = mean_shift(raw, *cloud);
  odometry_.accept(cloud, T, stamp, e.failed, e.quality, inertial.has_value());
  reference_ = {T * m.T_stamp(t_mean), stamp + t_mean};
  if (e.failed) {  // placed by the prediction: no velocity measured
    previous_mean_.reset(), before_previous_.reset(), previous_.reset();
    gyro_references_.clear();
  } else {
    if (gyro) observe_gyro(reference_);
    previous_mean_ = mean;
    if (auto r = revise_previous(reference_)) e.revised = std::move(r);
    before_previous_.reset();
    if (previous_) before_previous_ = previous_->reference;
    previous_ = Revisable{reference_, std::move(raw), cloud, stamp, frames_, m, T};
  }
  e.T_world_frame = T;
  e.deskewed = true;
  e.gyro = gyro != nullptr;
  e.inertial = inertial.has_value();
  return e;
}

std::optional<SweepOdometry::MeanVelocity> SweepOdometry::registered_mean(const Eigen::Isometry3d& T_world_mean, double time,
                                                                          bool degenerate) const {
  const auto since = [&](const SweepReference& from) -> std::optional<MeanVelocity> {
    const double span = time - from.stamp;
    if (span <= 1e-6) return std::nullopt;
    return MeanVelocity{se3_log(from.pose.inverse() * T_world_mean) / span, from.stamp + 0.5 * span};
  };
  const std::optional<MeanVelocity> last = since(reference_);
  // Where a sweep's geometry hardly tells a turn from a sideways motion (a straight road's rails
  // and lane edges), the error of its registration returns through its own deskewing: the velocity
  // since the last sweep carries it twice with opposite signs, and the drive swings from side to side
  // with growing amplitude. Half of the velocity since the sweep before cancels that alternation;
  // elsewhere it would only lag behind a fast change of the turn rate (a corner).
  const std::optional<MeanVelocity> two = degenerate && before_previous_ ? since(*before_previous_) : std::nullopt;
  if (!last || !two) return last;
  return MeanVelocity{0.5 * (last->velocity + two->velocity), 0.5 * (last->time + two->time)};
}

SweepOdometry::SweepMotion SweepOdometry::sweep_motion(const MeanVelocity& mean, double stamp,
                                                       std::shared_ptr<const GyroSweep> gyro) const {
  SweepMotion m;
  m.gyro = std::move(gyro);
  const double between = previous_mean_ ? mean.time - previous_mean_->time : 0.0;
  // Half the acceleration the two give: in full it fed registration noise back into the next sweep
  // and could swing out of a fast corner and diverge. Mean velocities closer
  // than a quarter of a 10 Hz sweep would amplify their noise.
  if (between > 0.025) m.acceleration = 0.5 * (mean.velocity - previous_mean_->velocity) / between;
  m.velocity = mean.velocity - (mean.time - stamp) * m.acceleration;
  return m;
}

}  // namespace gcmap
