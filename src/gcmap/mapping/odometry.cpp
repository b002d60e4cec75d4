#include "gcmap/mapping/odometry.hpp"

#include <algorithm>
#include <cmath>

#include "gcmap/core/se3.hpp"
#include "gcmap/registration/registration.hpp"

namespace gcmap {

namespace {

// Stamps of a fixed-rate sensor differ by rounding (0.1 * f) and driver jitter only: below this
// the intervals count as equal and the motion is extrapolated unscaled, bit for bit as without
// stamps (0.1 ms is 1 mm at 10 m/s).
constexpr double kEqualIntervals = 1e-4;

}  // namespace

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
  keyframes_.emplace_back(T, frame);
  while (static_cast<int>(keyframes_.size()) > config_.model_keyframes) keyframes_.pop_front();
  model_ = std::make_unique<GaussianVoxelMap>(config_.voxel_resolution);
  for (const auto& [pose, cloud] : keyframes_) model_->insert(*cloud, pose);
  model_->finalize();
}

Eigen::Isometry3d Odometry::track(const std::shared_ptr<const PointCloud>& frame, std::optional<double> stamp, bool* ok) {
  const bool usable = frame && frame->size() >= 100 && frame->has_covs();
  if (ok) *ok = usable;
  last_failed_ = false;
  if (!usable) {
    const Eigen::Isometry3d T = predict(stamp);
    set_pose(T, stamp);
    return T;
  }
  if (!model_) {
    set_pose(frames_ == 0 ? Eigen::Isometry3d::Identity() : predict(stamp), stamp);
    add_keyframe(frame, last_);
    return last_;
  }
  const Eigen::Isometry3d T = estimate(*frame, predict(stamp), &last_failed_);
  accept(frame, T, stamp);
  return last_;
}

Eigen::Isometry3d Odometry::estimate(const PointCloud& frame, const Eigen::Isometry3d& guess, bool* failed) const {
  if (failed) *failed = false;
  if (!model_) return guess;
  RegistrationConfig reg;
  reg.max_iterations = config_.max_iterations;
  const double min_inliers = config_.retry_inlier_fraction * frame.size();
  RegistrationResult r = align_vgicp(frame, *model_, guess, reg);
  if (r.num_inliers < min_inliers) {
    // Low overlap: a wrong prediction (a gap, a turn) may have led into a local minimum. Retry
    // from zero motion and, with twice the voxel size (a wider basin), from both guesses.
    GaussianVoxelMap coarse(2.0 * config_.voxel_resolution);
    for (const auto& [pose, cloud] : keyframes_) coarse.insert(*cloud, pose);
    coarse.finalize();
    for (int k = 0; k < 3; ++k) {
      const Eigen::Isometry3d from = k == 0 ? last_ : align_vgicp(frame, coarse, k == 1 ? guess : last_, reg).T_target_source;
      const RegistrationResult retry = align_vgicp(frame, *model_, from, reg);
      if (retry.num_inliers > r.num_inliers || (retry.num_inliers == r.num_inliers && retry.error < r.error)) r = retry;
    }
  }
  const bool far = (guess.inverse() * r.T_target_source).translation().norm() > config_.retry_distance;
  const bool bad = r.num_inliers <= 50 || (r.num_inliers < min_inliers && far);
  if (failed) *failed = bad;
  return bad ? guess : r.T_target_source;
}

void Odometry::accept(const std::shared_ptr<const PointCloud>& frame, const Eigen::Isometry3d& T, std::optional<double> stamp) {
  if (!model_) {
    set_pose(T, stamp);
    add_keyframe(frame, T);
    return;
  }
  set_pose(T, stamp);
  const Eigen::Isometry3d delta = keyframes_.back().first.inverse() * T;
  if (delta.translation().norm() > config_.keyframe_distance ||
      rotation_angle(delta) > config_.keyframe_angle_deg * M_PI / 180.0) {
    add_keyframe(frame, T);
  }
}

}  // namespace gcmap
