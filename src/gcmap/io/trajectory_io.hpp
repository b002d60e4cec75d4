#pragma once
#include <Eigen/Geometry>
#include <string>
#include <string_view>
#include <vector>

namespace gcmap {

// kitti: 12 numbers (3x4 row-major) per line; tum: "t x y z qx qy qz qw";
// named: "NAME x y z qx qy qz qw" (the graph.txt of shared/data/kitti07_submaps).
enum class TrajectoryFormat { kitti, tum, named };

struct Trajectory {
  TrajectoryFormat format = TrajectoryFormat::kitti;
  std::vector<Eigen::Isometry3d> poses;
  std::vector<double> stamps;      // tum
  std::vector<std::string> names;  // named
  size_t size() const { return poses.size(); }
};

// Detects the format from the first data line; every line must agree. Comments (#) and blank lines
// are skipped. Throws Error("PATH:LINE: ...") on anything malformed or non-finite, and on a
// translation component beyond 1e7 m (no position on Earth; it would overflow the metrics).
Trajectory read_trajectory(const std::string& path);
// The same on text in memory (fuzzed); `name` stands for the path in messages.
Trajectory parse_trajectory(std::string_view text, const std::string& name);
void write_trajectory(const std::string& path, const Trajectory& trajectory);

TrajectoryFormat parse_trajectory_format(const std::string& name);

// KITTI calib.txt: returns Tr (velodyne -> camera 0).
Eigen::Isometry3d read_kitti_calib_tr(const std::string& path);
Eigen::Isometry3d parse_kitti_calib_tr(std::string_view text, const std::string& name);

}  // namespace gcmap
