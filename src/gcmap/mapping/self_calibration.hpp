#pragma once
// Per-beam elevation offsets estimated by a run itself, before it maps: the odometry of the first
// frames places every n-th scan, the walls level that trajectory, and ElevationCalibration::estimate
// compares far ground with the ground other scans saw from close by. A spinning sensor's beam bias
// is what makes the LiDAR-only odometry pitch and drift on long drives (docs/pipeline.md); mapping
// the same scans corrected removes most of it.
#include <atomic>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "gcmap/calibration/elevation_calibration.hpp"
#include "gcmap/core/scan_source.hpp"
#include "gcmap/mapping/config.hpp"
#include "gcmap/mapping/pipeline.hpp"

namespace gcmap {

struct SelfCalibration {
  std::shared_ptr<const ElevationCalibration> calibration;  // null: nothing estimated (see summary)
  std::string summary;  // one line: from what it was estimated and what it found, or why not
  int frames = 0;       // frames read
  int scans = 0;        // scans in the estimate
  int bins = 0;         // elevations given an offset
  int passes = 0;       // odometry passes that ended in an estimate
  double travelled = 0.0, largest_deg = 0.0;
  std::vector<Eigen::Isometry3d> odometry;  // the first pass's: the scans as they came
};

// Reads the first config.calibration.frames scans of a source from `open` once per pass
// (calibration.passes): the first pass's odometry places the scans as they came, each later one's
// the scans corrected by the previous estimate. options.kitti_hdl64 applies; its calibration must be
// null. on_frame: after each frame's odometry, counting on over the passes. Nothing is estimated for
// a sensor without rings of fixed elevation (non-repetitive patterns), or when the sensor travels
// less than calibration.min_travel.
SelfCalibration self_calibrate_elevation(const std::function<std::unique_ptr<ScanSource>()>& open, const MappingConfig& config,
                                         const PipelineOptions& options, const std::function<void(int frame)>& on_frame = {},
                                         const std::atomic<bool>* stop = nullptr);

}  // namespace gcmap
