#include "gcmap/mapping/odometry.hpp"

#include "gcmap/registration/registration.hpp"

namespace gcmap {

Eigen::Isometry3d Odometry::predict() const {
  if (frames_ < 2) return last_;
  return last_ * (previous_.inverse() * last_);
}

void Odometry::set_pose(const Eigen::Isometry3d& T) {
  previous_ = frames_ > 0 ? last_ : T;
  last_ = T;
  ++frames_;
}

void Odometry::add_keyframe(const std::shared_ptr<const PointCloud>& frame, const Eigen::Isometry3d& T) {
  keyframes_.emplace_back(T, frame);
  while (static_cast<int>(keyframes_.size()) > config_.model_keyframes) keyframes_.pop_front();
  model_ = std::make_unique<GaussianVoxelMap>(config_.voxel_resolution);
  for (const auto& [pose, cloud] : keyframes_) model_->insert(*cloud, pose);
  model_->finalize();
}

Eigen::Isometry3d Odometry::track(const std::shared_ptr<const PointCloud>& frame, bool* ok) {
  const bool usable = frame && frame->size() >= 100 && frame->has_covs();
  if (ok) *ok = usable;
  if (!usable) {
    const Eigen::Isometry3d T = predict();
    set_pose(T);
    return T;
  }
  if (!model_) {
    set_pose(frames_ == 0 ? Eigen::Isometry3d::Identity() : predict());
    add_keyframe(frame, last_);
    return last_;
  }
  accept(frame, estimate(*frame, predict()));
  return last_;
}

Eigen::Isometry3d Odometry::estimate(const PointCloud& frame, const Eigen::Isometry3d& guess) const {
  if (!model_) return guess;
  RegistrationConfig reg;
  reg.max_iterations = config_.max_iterations;
  const RegistrationResult r = align_vgicp(frame, *model_, guess, reg);
  return r.num_inliers > 50 ? r.T_target_source : guess;
}

void Odometry::accept(const std::shared_ptr<const PointCloud>& frame, const Eigen::Isometry3d& T) {
  if (!model_) {
    set_pose(T);
    add_keyframe(frame, T);
    return;
  }
  set_pose(T);
  const Eigen::Isometry3d delta = keyframes_.back().first.inverse() * T;
  if (delta.translation().norm() > config_.keyframe_distance ||
      rotation_angle(delta) > config_.keyframe_angle_deg * M_PI / 180.0) {
    add_keyframe(frame, T);
  }
}

}  // namespace gcmap
