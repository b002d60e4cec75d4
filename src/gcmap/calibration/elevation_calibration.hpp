#pragma once
// Per-beam elevation correction of a spinning LiDAR. A factory calibration off by 0.1 to 0.2 deg
// per beam lifts or sinks a ring of far ground by 9 to 17 cm at 50 m; the rings travel with the
// sensor, so every scan sees the ground bent the same way and the odometry pitches as it goes. Scans
// registered as they go cannot tell this bend from their own pitch (the ground far ahead was only
// ever seen from farther), so the offsets are estimated from scans placed by a trajectory: each
// point against the level ground that the scans saw from close by. A trajectory that does not share
// the error (a reference) gives them all back; the run's own gives back the differences between
// beams, and their part that is smooth in range only once levelled by the walls (level_with_walls).
#include <cstdint>
#include <string>
#include <vector>

#include "gcmap/core/point_cloud.hpp"
#include "gcmap/core/se3.hpp"

namespace gcmap {

// A scan for ElevationCalibration::estimate: points deskewed into the sensor frame at the stamp,
// with covariances, and each point's bin (ElevationCalibration::bins, taken before deskewing).
struct CalibrationScan {
  PointCloud cloud;
  std::vector<int16_t> bins;
  Eigen::Isometry3d T_world_sensor = Eigen::Isometry3d::Identity();
};

// A prepared scan (sensor frame at its stamp, per-point times relative to it) as the estimate takes
// it: binned, then deskewed by `velocity` ([omega; rho] per second, none: as it is), times and
// intensities dropped.
CalibrationScan calibration_scan(PointCloud cloud, const Eigen::Isometry3d& T_world_sensor, const Vector6d* velocity);

struct CalibrationEstimate {
  double near_range = 15.0;  // m: points closer than this make the reference ground
  double voxel_resolution = 0.5;
  int iterations = 3;
  int min_points = 200;  // level-ground points a bin needs for an offset
};

// Removes a trajectory's slow roll and pitch drift, such as these very errors cause: walls, poles
// and trunks stand vertical, so the normals of a scan's steep surfaces must lie level in the world.
// Each scan's tilt is averaged over `window` scans either side, and the positions are re-integrated
// with the levelled orientations. Scans in trajectory order.
void level_with_walls(std::vector<CalibrationScan>& scans, int window = 10);
// The one roll and pitch that stand the steep surfaces of all `scans` (clouds with covariances,
// placed by T_world_sensor) upright together: R with (R n).z = 0 for their normals, no turn about z.
// A map made in the first scan's frame leans as that scan did; a 2-D grid of it is projected along
// this R's vertical. The identity where no wall holds a direction.
Eigen::Matrix3d levelling_rotation(const std::vector<CalibrationScan>& scans);

// Offsets in 0.1 deg bins of the measured elevation (a bin per beam of a spinning sensor).
class ElevationCalibration {
 public:
  ElevationCalibration();
  // Text: one "elevation_deg offset_deg" line per calibrated bin, '#' comments. Throws Error naming
  // `name` and the line for anything else.
  static ElevationCalibration parse(const std::string& text, const std::string& name);
  static ElevationCalibration load(const std::string& path);
  std::string to_text() const;

  // The offset (rad) of points measured at this elevation (rad).
  double offset(double elevation) const;
  // Sets offsets smaller than `threshold` (rad) in magnitude to zero.
  void drop_below(double threshold);
  // Elevations given an offset, and the largest offset (rad) in magnitude.
  int num_offsets() const;
  double largest_offset() const;
  // Turns each point (sensor frame) up by its bin's offset, keeping its range and azimuth.
  void correct(PointCloud& cloud) const;
  // Each point's bin, -1 outside +-45 deg or on the axis.
  static std::vector<int16_t> bins(const PointCloud& cloud);
  // A raw scan from beams at fixed elevations (a spinning multi-beam sensor): most of its points
  // beyond 5 m fall into few of the 0.1 deg bins its elevations span. False for non-repetitive
  // patterns (Livox), whose bins would each mix many directions.
  static bool has_rings(const PointCloud& raw);
  // Gauss-Newton on every bin's offset: points against the level ground made of the near points.
  static ElevationCalibration estimate(const std::vector<CalibrationScan>& scans, const CalibrationEstimate& options = {});

 private:
  std::vector<double> offset_;  // rad per bin
};

}  // namespace gcmap
