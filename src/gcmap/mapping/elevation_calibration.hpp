#pragma once
// Per-beam elevation correction of a spinning LiDAR. A factory calibration off by 0.1 to 0.2 deg
// per beam lifts or sinks a ring of far ground by 9 to 17 cm at 50 m; the rings travel with the
// sensor, so every scan sees the ground bent the same way and the odometry tilts (on the realistic
// `city`, 1.2 % t_rel of which 1 % goes with exact offsets). Scans registered as they go cannot
// tell this bend from their own pitch (the ground far ahead was only ever seen from farther), so
// the offsets are estimated after a run: each far point against the ground that other scans of the
// run saw from close by, placed by the run's trajectory.
#include <cstdint>
#include <string>
#include <vector>

#include "gcmap/core/point_cloud.hpp"

namespace gcmap {

// A scan for ElevationCalibration::estimate: points deskewed into the sensor frame at the stamp,
// with covariances, and each point's bin (ElevationCalibration::bins, taken before deskewing).
struct CalibrationScan {
  PointCloud cloud;
  std::vector<int16_t> bins;
  Eigen::Isometry3d T_world_sensor = Eigen::Isometry3d::Identity();
};

struct CalibrationEstimate {
  double near_range = 15.0;     // m: points closer than this make the reference ground
  double voxel_resolution = 0.5;
  int iterations = 3;
  int min_points = 200;         // far ground points a bin needs for an offset
};

// Offsets in 0.1 deg bins of the measured elevation (a bin per beam of a spinning sensor).
class ElevationCalibration {
 public:
  ElevationCalibration();
  // Text: one "elevation_deg offset_deg" line per calibrated bin, '#' comments. Throws Error naming
  // `name` and the line for anything else.
  static ElevationCalibration parse(const std::string& text, const std::string& name);
  static ElevationCalibration load(const std::string& path);
  std::string to_text() const;

  bool empty() const;
  // The offset (rad) of points measured at this elevation (rad).
  double offset(double elevation) const;
  // Rotates each point (sensor frame) to its bin's elevation plus the offset.
  void correct(PointCloud& cloud) const;
  // Each point's bin, -1 outside +-45 deg or on the axis.
  static std::vector<int16_t> bins(const PointCloud& cloud);
  // Gauss-Newton on every bin's offset: far points against level ground made of the near points.
  static ElevationCalibration estimate(const std::vector<CalibrationScan>& scans, const CalibrationEstimate& options = {});

 private:
  std::vector<double> offset_;  // rad per bin
};

}  // namespace gcmap
