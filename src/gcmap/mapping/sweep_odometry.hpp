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
};

class SweepOdometry {
 public:
  SweepOdometry(const MappingConfig& config, std::shared_ptr<LinearizationBackend> backend);

  // The pose of a prepared scan (null: unusable, placed by the prediction) at `stamp`, stamps
  // non-decreasing. A scan with per-point times is deskewed in place into the sensor frame at the
  // stamp. T_odom: an external pose taken instead of registration (it still drives deskewing).
  SweepEstimate track(const std::shared_ptr<PointCloud>& cloud, double stamp,
                      const std::optional<Eigen::Isometry3d>& T_odom = std::nullopt);

 private:
  SweepEstimate track_deskewed(const std::shared_ptr<PointCloud>& cloud, double stamp, double dt);

  bool deskew_;
  Odometry odometry_;
  // The previous frame's pose and stamp.
  std::optional<std::pair<Eigen::Isometry3d, double>> last_;
  // The last frame's pose at the instant its registration fixes best (see track_deskewed): the
  // mean point time of a deskewed sweep, else the scan stamp.
  struct SweepReference {
    Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
    double stamp = 0.0;
  };
  SweepReference reference_;
};

}  // namespace gcmap
