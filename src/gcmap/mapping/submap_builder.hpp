#pragma once
// Local mapping (paper Section III-A): keyframes chosen by overlap, a fully connected VGICP graph
// over a submap's keyframes, and their merge into one submap cloud.
#include <memory>
#include <optional>

#include "gcmap/core/imu_sample.hpp"
#include "gcmap/core/timer.hpp"
#include "gcmap/graph/backend.hpp"
#include "gcmap/mapping/config.hpp"
#include "gcmap/mapping/submap.hpp"

namespace gcmap {

struct FactorGraph;

// What became of a frame: a keyframe of a submap, skipped (overlaps its predecessor above
// local.th_max; placed from it) or unusable (empty or too few points; placed by odometry).
enum class FrameStatus { keyframe, skipped, unusable };
const char* to_string(FrameStatus status);

// What a keyframe needs of its cloud alone, in the cloud's frame. The pipeline makes it while the
// scan is prepared, in parallel, where the cloud stays as prepared (no deskewing).
struct KeyframeShape {
  std::shared_ptr<const GaussianVoxelMap> voxels;  // local.voxel_resolution
  ScanContext descriptor;                          // when loop.enabled
};
KeyframeShape keyframe_shape(const PointCloud& cloud, const LocalMappingConfig& local, const LoopConfig& loop);

struct LocalMappingStats {
  TimingStats factors, optimization;  // per closed submap
  size_t gyro_factors = 0;            // between consecutive keyframes of a submap
};

class SubmapBuilder {
 public:
  // Of global: the submap voxel maps' resolution and factor_source_points; of loop: the keyframe
  // descriptors (enabled, scan_context).
  SubmapBuilder(const LocalMappingConfig& local, const GlobalMappingConfig& global, const LoopConfig& loop,
                std::shared_ptr<LinearizationBackend> backend);

  struct Result {
    FrameStatus status = FrameStatus::unusable;
    int anchor = -1;               // the keyframe (frame index) this frame is placed from; -1: none yet
    std::optional<Submap> closed;  // a submap this frame completed
  };
  // Frames in order; a null or small cloud is unusable. A submap that a keyframe completes closes
  // with the next frame (or close()), so that its last keyframe can still be revised. shape: the
  // cloud's keyframe_shape when made ahead. gyro: the gyro's rotation since the previous frame;
  // consecutive keyframes it spans get that rotation between them as a factor.
  Result add_frame(int frame, const std::shared_ptr<const PointCloud>& cloud, const Eigen::Isometry3d& T_odom,
                   std::optional<KeyframeShape> shape = std::nullopt, const std::optional<GyroRotation>& gyro = std::nullopt);
  // Closes the open submap, if any.
  std::optional<Submap> close();
  // Replaces the cloud and odometry pose of a keyframe of the open submap (its sweep deskewed
  // again, see SweepRevision); false when the frame is no open keyframe.
  bool revise(int frame, const std::shared_ptr<const PointCloud>& cloud, const Eigen::Isometry3d& T_odom);
  // The gyro was found misplaced: its rotations go.
  void drop_gyro();

  const LocalMappingStats& stats() const { return stats_; }

 private:
  struct Keyframe {
    int frame;
    Eigen::Isometry3d T_odom;
    std::shared_ptr<const PointCloud> cloud;
    std::shared_ptr<const GaussianVoxelMap> voxels;  // local resolution, keyframe frame
    ScanContext descriptor;                          // when explicit loops are on
    std::optional<GyroRotation> gyro;                // from the previous keyframe of the submap
  };
  // shape: the cloud's, when made ahead; else made here.
  Keyframe make_keyframe(int frame, const Eigen::Isometry3d& T_odom, const std::shared_ptr<const PointCloud>& cloud,
                         std::optional<KeyframeShape> shape) const;
  // Keyframe poses in the submap frame, optimized with every keyframe pair as a factor; noise:
  // how much the keyframes disagree at the optimum (Submap::keyframe_noise).
  std::vector<Eigen::Isometry3d> optimize_keyframes(const Eigen::Isometry3d& T_odom_submap, std::optional<float>& noise);
  void add_gyro_factors(FactorGraph& graph);
  Submap merge(Submap s) const;

  LocalMappingConfig config_;
  GlobalMappingConfig global_;
  LoopConfig loop_;
  std::shared_ptr<LinearizationBackend> backend_;
  std::vector<Keyframe> open_;
  bool complete_ = false;  // the open submap closes with the next frame
  int next_id_ = 0;
  int last_keyframe_ = -1;
  std::optional<GyroRotation> since_keyframe_;  // the gyro's rotation since the last keyframe
  LocalMappingStats stats_;
};

}  // namespace gcmap
