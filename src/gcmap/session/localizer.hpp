#pragma once
// Localization on a prior map (a session of an earlier run): each scan is tracked by odometry and
// pinned to the fixed prior submaps by matching-cost factors, optimized on the same LM as mapping.
// Global initialization and recovery use the prior keyframes' ScanContext places, verified by GICP.
#include <memory>
#include <optional>

#include "gcmap/mapping/pipeline.hpp"

namespace gcmap {

// The fixed map: submaps with clouds, voxel maps and keyframe descriptors, and their poses.
struct PriorMap {
  std::vector<Submap> submaps;
  std::vector<Eigen::Isometry3d> T_map_submap;
};

enum class LocalizationStatus { tracking, lost, relocalized };
const char* to_string(LocalizationStatus status);

struct LocalizedFrame {
  int index = 0;
  double stamp = 0.0;
  LocalizationStatus status = LocalizationStatus::lost;
  Eigen::Isometry3d T_map_frame = Eigen::Isometry3d::Identity();  // the prediction while lost
  double map_overlap = 0.0;                                       // fraction of the frame's points in prior-map voxels
  int prior_submaps = 0;                                          // prior submaps the frame was matched against
  bool deskewed = false;  // motion-compensated by the odometry (per-point times, preprocess.deskew)
  double ms = 0.0;
};

class Localizer {
 public:
  // Like the pipeline it composes mapping's modules, so it takes the run's config and reads:
  // preprocess and odometry (its sweep odometry), loop (ScanContext places and verification),
  // localize, and global.voxel_resolution and global.th_min (the prior's voxel maps must be at it).
  Localizer(std::shared_ptr<const PriorMap> prior, const MappingConfig& config,
            std::shared_ptr<LinearizationBackend> backend = nullptr, PipelineOptions options = {});
  // The first frame's pose in the map; without it the first frame is globally initialized.
  void set_initial_pose(const Eigen::Isometry3d& T_map_frame) { initial_ = T_map_frame; }

  LocalizedFrame add_scan(PointCloud scan, double stamp);
  const std::vector<LocalizedFrame>& frames() const { return frames_; }

 private:
  // Pose by matching-cost factors to every overlapping prior submap plus the odometry motion
  // from the previous frame; returns false when the map does not hold the frame.
  bool track(const std::shared_ptr<const PointCloud>& cloud, const Eigen::Isometry3d& guess,
             const std::optional<Eigen::Isometry3d>& previous, LocalizedFrame& out);
  std::optional<Eigen::Isometry3d> global_initialization(const PointCloud& cloud);
  double map_overlap(const PointCloud& cloud, const Eigen::Isometry3d& T_map_frame, const std::vector<int>& submaps) const;
  std::vector<int> nearby_submaps(const Eigen::Isometry3d& T_map_frame) const;

  std::shared_ptr<const PriorMap> prior_;
  MappingConfig config_;
  std::shared_ptr<LinearizationBackend> backend_;
  PipelineOptions options_;
  SweepOdometry odometry_;
  ScanContextDatabase places_;
  std::vector<std::pair<int, int>> place_keyframe_;  // (submap, keyframe index)
  std::optional<Eigen::Isometry3d> initial_;
  std::vector<LocalizedFrame> frames_;
  std::vector<Eigen::Isometry3d> odometry_poses_;
  int lost_since_ = 0;           // frames since the last global initialization attempt while lost
  bool localized_once_ = false;  // a pose in the map is known (else no dead reckoning)
};

}  // namespace gcmap
