#include "gcmap/odometry/odometry.hpp"

#include <algorithm>
#include <array>
#include <cmath>

#include <Eigen/Eigenvalues>

#include "gcmap/core/se3.hpp"
#include "gcmap/registration/registration.hpp"

namespace gcmap {

namespace {

// Stamps of a fixed-rate sensor differ by rounding (0.1 * f) and driver jitter only: below this
// the intervals count as equal and the motion is extrapolated unscaled, bit for bit as without
// stamps (0.1 ms is 1 mm at 10 m/s).
constexpr double kEqualIntervals = 1e-4;
constexpr double kSteadyRatio = 1.5;
constexpr int kMaxFailedStreak = 3;
// Retries search on voxels at least this large (m): the basin must span the prediction's error, a
// length of the motion, not of the registration's voxels.
constexpr double kRetryVoxel = 2.0;
// A registration matching under this share of what the recent ones matched sees another place (a
// jump in the recording) or a wrong minimum: how many points fall into model voxels depends on the
// voxel size and the sensor, their sudden drop does not.
constexpr double kCollapsedInliers = 0.5;
constexpr size_t kRecentRegistrations = 10;
// A model's first registrations (after a start or a gap) vary too much to be typical.
constexpr size_t kMinRecentRegistrations = 5;

RegistrationQuality registration_quality(const RegistrationResult& r, size_t points) {
  RegistrationQuality q;
  q.registered = true;
  q.inlier_fraction = points ? static_cast<double>(r.num_inliers) / points : 0.0;
  q.hessian = r.H;
  if (r.num_inliers == 0) return q;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(translation_information(r.H) / r.num_inliers);
  q.translation_information = eig.eigenvalues().cwiseMax(0.0);
  q.weak_direction = eig.eigenvectors().col(0);
  return q;
}

}  // namespace

const char* to_string(OdometryFailure f) {
  switch (f) {
    case OdometryFailure::none: return "none";
    case OdometryFailure::no_matches: return "hardly any point matched the local model";
    case OdometryFailure::stops_short: return "the registration stopped short of the predicted motion";
    case OdometryFailure::far_with_low_overlap: return "few points matched and the result lay far from the prediction";
    case OdometryFailure::overlap_collapsed: return "far fewer points matched than in the frames before";
  }
  return "";
}

Odometry::Odometry(const OdometryConfig& config, std::shared_ptr<LinearizationBackend> backend)
    : config_(config), backend_(backend ? std::move(backend) : std::make_shared<CpuBackend>()) {}

Eigen::Isometry3d Odometry::predict(std::optional<double> stamp) const {
  if (frames_ < 2) return last_;
  const Eigen::Isometry3d delta = previous_.inverse() * last_;
  if (!stamp || !last_stamp_ || !previous_stamp_) return last_ * delta;
  const double dt_last = *last_stamp_ - *previous_stamp_, dt_now = *stamp - *last_stamp_;
  if (std::abs(dt_now - dt_last) <= kEqualIntervals) return last_ * delta;
  // No velocity known (equal stamps), or too long ago to extrapolate: no motion.
  if (dt_last < kEqualIntervals || dt_now > config_.max_gap) return last_;
  const double ratio = std::min(dt_now / dt_last, config_.max_interval_ratio);
  return last_ * se3_exp(ratio * se3_log(delta));
}

void Odometry::set_pose(const Eigen::Isometry3d& T, std::optional<double> stamp) {
  previous_ = frames_ > 0 ? last_ : T;
  previous_stamp_ = frames_ > 0 ? last_stamp_ : stamp;
  last_ = T;
  last_stamp_ = stamp;
  ++frames_;
}

void Odometry::add_keyframe(const std::shared_ptr<const PointCloud>& frame, const Eigen::Isometry3d& T) {
  if (!model_) model_ = std::make_shared<GaussianVoxelMap>(config_.voxel_resolution, GaussianVoxelMap::Updates::incremental);
  if (model_.use_count() > 1) model_ = std::make_shared<GaussianVoxelMap>(*model_);
  keyframes_.emplace_back(T, frame);
  model_->insert(*frame, T);
  while (static_cast<int>(keyframes_.size()) > config_.model_keyframes) {
    model_->remove(*keyframes_.front().second, keyframes_.front().first);
    keyframes_.pop_front();
  }
  model_->finalize();
}

bool Odometry::revise_keyframe(const PointCloud& old, const std::shared_ptr<const PointCloud>& frame,
                               const Eigen::Isometry3d& T) {
  const auto it = std::find_if(keyframes_.begin(), keyframes_.end(), [&](const auto& k) { return k.second.get() == &old; });
  if (it == keyframes_.end()) return false;
  if (model_.use_count() > 1) model_ = std::make_shared<GaussianVoxelMap>(*model_);
  model_->remove(*it->second, it->first);
  *it = {T, frame};
  model_->insert(*frame, T);
  model_->finalize();
  return true;
}

Eigen::Isometry3d Odometry::track(const std::shared_ptr<const PointCloud>& frame, std::optional<double> stamp, bool* ok,
                                  const std::optional<Eigen::Isometry3d>& guess) {
  const bool usable = frame && frame->size() >= 100 && frame->has_covs();
  if (ok) *ok = usable;
  last_failed_ = false;
  last_quality_ = {};
  const Eigen::Isometry3d predicted = guess ? *guess : predict(stamp);
  if (!usable) {
    set_pose(predicted, stamp);
    return predicted;
  }
  if (!model_) {
    set_pose(frames_ == 0 ? Eigen::Isometry3d::Identity() : predicted, stamp);
    add_keyframe(frame, last_);
    return last_;
  }
  const Guess kind = guess && frames_ >= 2 ? Guess::steady : guess_kind(stamp);
  const Eigen::Isometry3d T = estimate(*frame, predicted, kind, &last_failed_, &last_quality_);
  accept(frame, T, stamp, last_failed_, last_quality_, guess.has_value());
  return last_;
}

Odometry::Guess Odometry::guess_kind(std::optional<double> stamp) const {
  // Frames placed by the prediction in a row mean the velocity itself may be wrong.
  if (frames_ < 2 || failed_streak_ >= kMaxFailedStreak) return Guess::rest;
  if (!stamp || !last_stamp_ || !previous_stamp_) return Guess::steady;
  const double dt_last = *last_stamp_ - *previous_stamp_, dt_now = *stamp - *last_stamp_;
  if (std::abs(dt_now - dt_last) <= kEqualIntervals) return Guess::steady;
  if (dt_last < kEqualIntervals || dt_now > config_.max_gap) return Guess::rest;
  // Driver jitter leaves the prediction as good as at equal intervals; a dropped message does not.
  return dt_now < kSteadyRatio * dt_last && dt_last < kSteadyRatio * dt_now ? Guess::steady : Guess::scaled;
}

double Odometry::typical_inlier_fraction() const {
  if (inlier_fractions_.size() < kMinRecentRegistrations) return 0.0;
  std::array<double, kRecentRegistrations> v;
  const auto end = std::copy(inlier_fractions_.begin(), inlier_fractions_.end(), v.begin());
  const auto mid = v.begin() + (end - v.begin()) / 2;
  std::nth_element(v.begin(), mid, end);
  return *mid;
}

std::shared_ptr<const GaussianVoxelMap> Odometry::model_at(double resolution) const {
  auto map = std::make_shared<GaussianVoxelMap>(resolution);
  for (const auto& [pose, cloud] : keyframes_) map->insert(*cloud, pose);
  map->finalize();
  return map;
}

Eigen::Isometry3d Odometry::estimate(const PointCloud& frame, const Eigen::Isometry3d& guess, Guess kind, bool* failed,
                                     RegistrationQuality* quality) const {
  if (failed) *failed = false;
  if (quality) *quality = {};
  if (!model_) return guess;
  RegistrationConfig reg;
  reg.max_iterations = config_.max_iterations;
  if (kind == Guess::rest) {
    // Nothing to compare the result with: standing still is no prediction, only the start.
    const Eigen::Isometry3d coarse = backend_->align(frame, model_at(config_.start_voxel_resolution), guess, reg).T_target_source;
    const RegistrationResult r = backend_->align(frame, model_, coarse, reg);
    if (failed) *failed = r.num_inliers <= 50;
    if (quality) *quality = registration_quality(r, frame.size());
    if (quality && r.num_inliers <= 50) quality->failure = OdometryFailure::no_matches;
    return r.num_inliers <= 50 ? guess : r.T_target_source;
  }
  const double min_inliers = config_.retry_inlier_fraction * frame.size();
  const double collapsed_inliers = kCollapsedInliers * typical_inlier_fraction() * frame.size();
  const double retry_resolution = std::max(2.0 * config_.voxel_resolution, kRetryVoxel);
  RegistrationResult r = backend_->align(frame, model_, guess, reg);
  const auto far = [&](const RegistrationResult& x) {
    return (guess.inverse() * x.T_target_source).translation().norm() > config_.retry_distance;
  };
  const auto doubtful = [&](const RegistrationResult& x) {
    return x.num_inliers < min_inliers && (far(x) || x.num_inliers < collapsed_inliers);
  };
  // Low overlap near a steady guess is no reason for doubt: on a fast straight road the model's
  // ground rings cover little of the scan. A sudden drop against the frames before is.
  if (kind == Guess::scaled ? r.num_inliers < min_inliers : doubtful(r)) {
    // A wrong prediction (a gap, a turn) may have led into a local minimum. Retry from zero
    // motion and, on coarser voxels (a wider basin), from both guesses.
    const auto coarse = model_at(retry_resolution);
    for (int k = 0; k < 3; ++k) {
      const Eigen::Isometry3d from = k == 0 ? last_ : backend_->align(frame, coarse, k == 1 ? guess : last_, reg).T_target_source;
      const RegistrationResult retry = backend_->align(frame, model_, from, reg);
      if (retry.num_inliers > r.num_inliers || (retry.num_inliers == r.num_inliers && retry.error < r.error)) r = retry;
    }
  }
  // Zero motion is a false minimum on a fast straight road: the scan's ground rings fall on those
  // of the last keyframe, and road-parallel structure does not object. Over one equal interval,
  // stopping retry_distance short of the constant-velocity guess (braking 10 m/s in 0.1 s) is no
  // motion a vehicle makes: retried from the guess on twice the voxel size, it fails if it persists.
  // Progress along the guessed motion (a result past zero motion, backwards, stops short too).
  const Eigen::Vector3d guess_motion = (last_.inverse() * guess).translation();
  const double guess_length = guess_motion.norm();
  const auto stops_short = [&](const RegistrationResult& x) {
    const Eigen::Vector3d motion = (last_.inverse() * x.T_target_source).translation();
    return motion.dot(guess_motion) < guess_length * (guess_length - config_.retry_distance);
  };
  const bool implausible = kind == Guess::steady && stops_short(r);
  if (implausible) {
    const auto coarse = model_at(retry_resolution);
    r = backend_->align(frame, model_, backend_->align(frame, coarse, guess, reg).T_target_source, reg);
  }
  const bool bad = r.num_inliers <= 50 || (implausible && stops_short(r)) || doubtful(r);
  if (failed) *failed = bad;
  if (quality) {
    *quality = registration_quality(r, frame.size());
    if (bad)
      quality->failure = r.num_inliers <= 50             ? OdometryFailure::no_matches
                         : implausible && stops_short(r) ? OdometryFailure::stops_short
                         : far(r)                        ? OdometryFailure::far_with_low_overlap
                                                         : OdometryFailure::overlap_collapsed;
  }
  return bad ? guess : r.T_target_source;
}

void Odometry::accept(const std::shared_ptr<const PointCloud>& frame, const Eigen::Isometry3d& T, std::optional<double> stamp,
                      bool failed, const RegistrationQuality& quality, bool imu_placed) {
  failed_streak_ = failed ? failed_streak_ + 1 : 0;
  if (quality.registered && !failed) {
    inlier_fractions_.push_back(quality.inlier_fraction);
    if (inlier_fractions_.size() > kRecentRegistrations) inlier_fractions_.pop_front();
  }
  if (!model_) {
    set_pose(T, stamp);
    add_keyframe(frame, T);
    return;
  }
  set_pose(T, stamp);
  // Frames placed by the prediction in a row: the model no longer explains the scans (the
  // recording jumped elsewhere, or the odometry slipped). Searching on from rest against it can run
  // away for hundreds of frames: along a street a wrong velocity confirms itself. The next usable
  // frame starts a new model at the prediction instead, as at the start of a drive.
  if (failed_streak_ >= kMaxFailedStreak) {
    keyframes_.clear();
    model_.reset();
    inlier_fractions_.clear();
    return;
  }
  // A frame the constant-velocity prediction placed stays out of the model: where the prediction
  // erred (a handheld sensor's fast turn), the registrations after it took that error on. One the
  // IMU's state placed joins as any other: the model must move on with it through a canyon.
  if (failed && !imu_placed) return;
  // A model of one sweep is a poor target: its voxels hold a few points each, and a
  // non-repetitive pattern samples other surfaces in the next sweep, so a walker's first frames
  // registered against it far off. Until the model is full, every registered frame joins it.
  const bool filling = static_cast<int>(keyframes_.size()) < config_.model_keyframes;
  const Eigen::Isometry3d delta = keyframes_.back().first.inverse() * T;
  if (filling || delta.translation().norm() > config_.keyframe_distance ||
      rotation_angle(delta) > config_.keyframe_angle_deg * M_PI / 180.0) {
    add_keyframe(frame, T);
  }
}

}  // namespace gcmap
