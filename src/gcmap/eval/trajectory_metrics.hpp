#pragma once
#include <Eigen/Geometry>
#include <vector>

namespace gcmap {

using Poses = std::vector<Eigen::Isometry3d>;

// KITTI odometry devkit relative error: segments of 100..800 m starting every 10 frames,
// error = inv(delta_est) * delta_gt, averaged over all segments.
struct KittiSegmentError {
  double length = 0.0;
  double translation_percent = 0.0;
  double rotation_deg_per_100m = 0.0;
  size_t count = 0;
};
struct KittiError {
  double translation_percent = 0.0;    // "Mean ST" translational, %
  double rotation_deg_per_100m = 0.0;  // rotational, deg / 100 m
  size_t num_segments = 0;
  std::vector<KittiSegmentError> per_length;
};
KittiError kitti_relative_error(const Poses& gt, const Poses& est);

struct AbsoluteError {
  double rmse = 0.0, mean = 0.0, max = 0.0;
  Eigen::Isometry3d T_gt_est = Eigen::Isometry3d::Identity();  // alignment applied to est
};
// ATE after SE(3) Umeyama alignment of the estimated positions onto the ground truth.
AbsoluteError absolute_trajectory_error(const Poses& gt, const Poses& est);

// Frame-to-frame relative pose error.
struct RelativePoseError {
  double translation_rmse = 0.0, translation_mean = 0.0, translation_max = 0.0;  // m
  double rotation_rmse_deg = 0.0, rotation_mean_deg = 0.0, rotation_max_deg = 0.0;
};
RelativePoseError relative_pose_error(const Poses& gt, const Poses& est);

// How far each estimated pose's vertical (its frame's view of the world's z) is from the truth's,
// in degrees: for trajectories whose frames both have z up (gravity's), whatever their headings.
struct VerticalError {
  double rmse_deg = 0.0, mean_deg = 0.0, max_deg = 0.0;
};
VerticalError vertical_error(const Poses& gt, const Poses& est);

// Rigid transform (no scale) minimizing sum |a_i - (R b_i + t)|^2.
Eigen::Isometry3d umeyama_se3(const std::vector<Eigen::Vector3d>& a, const std::vector<Eigen::Vector3d>& b);

}  // namespace gcmap
