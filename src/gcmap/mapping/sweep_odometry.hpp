#pragma once
// The odometry front end the pipeline and the localizer share: scan-to-model registration
// (Odometry) with motion compensation of sweeps that carry per-point times (preprocess.deskew).
#include <memory>
#include <optional>

#include "gcmap/mapping/config.hpp"
#include "gcmap/mapping/odometry.hpp"

namespace gcmap {

struct SweepEstimate {
  Eigen::Isometry3d T_world_frame = Eigen::Isometry3d::Identity();  // at the scan stamp
  bool deskewed = false;
  bool failed = false;  // registration rejected (see Odometry::estimate): placed by the prediction
  // Once, at the second frame: the first sweep, deskewed now that the motion is known (it entered
  // the odometry's model smeared). The mapper should take it instead (Mapper::replace_frame_cloud).
  std::shared_ptr<const PointCloud> first_deskewed;
  int first_frame = -1;  // its index among the frames tracked
};

class SweepOdometry {
 public:
  SweepOdometry(const MappingConfig& config, std::shared_ptr<LinearizationBackend> backend);

  // The pose of a prepared scan (null: unusable, placed by the prediction) at `stamp`, stamps
  // non-decreasing. A scan with per-point times is deskewed in place into the sensor frame at the
  // stamp, unless no motion is known (the first frame, after a gap of odometry.max_gap). T_odom: an
  // external pose taken instead of registration (it still drives deskewing).
  SweepEstimate track(const std::shared_ptr<PointCloud>& cloud, double stamp,
                      const std::optional<Eigen::Isometry3d>& T_odom = std::nullopt);

 private:
  SweepEstimate track_deskewed(const std::shared_ptr<PointCloud>& cloud, double stamp, double dt);

  // A registered mean velocity [omega; rho] between two instants, and the middle of them.
  struct MeanVelocity {
    Vector6d velocity = Vector6d::Zero();
    double time = 0.0;
  };
  // The motion over a sweep from its stamp: velocity there, changing by acceleration per second.
  struct SweepMotion {
    Vector6d velocity = Vector6d::Zero(), acceleration = Vector6d::Zero();
    Vector6d at(double t) const { return t * velocity + 0.5 * t * t * acceleration; }  // log T_stamp_t
  };
  // `mean` with the previous sweep's mean velocity: linear in time (constant without one).
  SweepMotion sweep_motion(const MeanVelocity& mean, double stamp) const;

  // The first sweep entered the model as it came; with the first motion registered (smeared
  // against smeared, which cancels), it is deskewed and the model started again from it.
  std::shared_ptr<const PointCloud> restart_from_first(const Vector6d& velocity);

  OdometryConfig config_;
  std::shared_ptr<LinearizationBackend> backend_;
  bool deskew_;
  Odometry odometry_;
  int frames_ = 0;
  struct FirstSweep {
    PointCloud raw;
    double stamp = 0.0;
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    int frame = 0;
  };
  std::optional<FirstSweep> first_;  // until the second frame is registered
  // The previous frame's pose and stamp.
  std::optional<std::pair<Eigen::Isometry3d, double>> last_;
  // The last frame's pose at the instant its registration fixes best (see track_deskewed): the
  // mean point time of a deskewed sweep, else the scan stamp.
  struct SweepReference {
    Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
    double stamp = 0.0;
  };
  SweepReference reference_;
  std::optional<MeanVelocity> previous_mean_;  // the last deskewed sweep's
};

}  // namespace gcmap
