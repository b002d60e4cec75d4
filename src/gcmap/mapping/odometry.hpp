#pragma once
#include <deque>
#include <memory>

#include "gcmap/core/gaussian_voxel_map.hpp"
#include "gcmap/mapping/config.hpp"

namespace gcmap {

// LiDAR-only front end: scan-to-model VGICP against a voxel map of recent keyframes, started from
// a constant-velocity prediction.
class Odometry {
 public:
  explicit Odometry(const OdometryConfig& config) : config_(config) {}

  // T_world_frame of a preprocessed frame (with covariances). A frame too small to register (empty
  // or dropped scan) gets the constant-velocity prediction and *ok = false.
  Eigen::Isometry3d track(const std::shared_ptr<const PointCloud>& frame, bool* ok = nullptr);
  // The two halves of track() for a usable frame: scan-to-model registration from a guess (no
  // state change), then the accepted pose and possibly a new keyframe of the model.
  Eigen::Isometry3d estimate(const PointCloud& frame, const Eigen::Isometry3d& guess) const;
  void accept(const std::shared_ptr<const PointCloud>& frame, const Eigen::Isometry3d& T);
  bool has_model() const { return model_ != nullptr; }

  // The constant-velocity guess for the next frame (also used for frames that fail to load).
  Eigen::Isometry3d predict() const;
  // Accepts an externally given pose (e.g. --initial-trajectory) to keep the motion model going.
  void set_pose(const Eigen::Isometry3d& T);

 private:
  void add_keyframe(const std::shared_ptr<const PointCloud>& frame, const Eigen::Isometry3d& T);

  OdometryConfig config_;
  int frames_ = 0;
  Eigen::Isometry3d last_ = Eigen::Isometry3d::Identity(), previous_ = Eigen::Isometry3d::Identity();
  std::deque<std::pair<Eigen::Isometry3d, std::shared_ptr<const PointCloud>>> keyframes_;
  std::unique_ptr<GaussianVoxelMap> model_;
};

}  // namespace gcmap
