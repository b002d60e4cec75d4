#pragma once
// The scans behind a gcmap map output folder, in the map frame of its final trajectory: for the
// per-scan export and the occupancy grid (whose fallback, when the scans are gone, is the session).
#include <functional>
#include <optional>
#include <string>

#include "gcmap/core/point_cloud.hpp"
#include "gcmap/io/geo.hpp"
#include "gcmap/io/trajectory_io.hpp"
#include "gcmap/mapping/occupancy_grid.hpp"

namespace gcmap::cli {

// The recording the folder was mapped from: `given` (--scans) when not empty, else the input that
// OUT/stats.json names. Empty when that is not on disk (or stats.json names none).
std::string recorded_input(const std::string& out, const std::string& given);

// A scan in the map frame: each point moved by the pose at its own time (interpolated between the
// frame's pose and the next), intensities and times (s after `stamp`) kept.
struct MappedScan {
  size_t frame = 0;
  double stamp = 0.0;
  PointCloud cloud;                      // map frame
  std::vector<Eigen::Vector3f> origins;  // sensor positions over the sweep (one without per-point times)
  std::vector<uint16_t> origin_of;       // per point: index into origins
};

// Calls visit for every frame of `trajectory` (T_map_sensor at each stamp) with its scan from
// `input` (opened as the run of output folder `out` did: topic, times file), matched by stamp;
// loads in parallel, visit runs concurrently. Throws Error naming the input when a frame's stamp
// has no scan. progress(done, total) from the calling thread.
void for_each_mapped_scan(const std::string& out, const std::string& input, const Trajectory& trajectory,
                          const std::function<void(MappedScan&)>& visit, const std::function<void(size_t, size_t)>& progress);

struct GridResult {
  OccupancyGrid grid;
  std::string source;                                         // what the rays came from, in words
  Eigen::Matrix3d R_level_map = Eigen::Matrix3d::Identity();  // the grid's frame: the map frame levelled
  std::string levelling;                                      // how, in words
};

// The ENU origin of a run that GNSS georeferenced (OUT/stats.json "gnss"); none otherwise.
std::optional<Geodetic> recorded_enu_origin(const std::string& out);
// Whether the run in `out` had its map levelled by an IMU's gravity (stats.json).
bool recorded_gravity_level(const std::string& out);

// The grid is made in the map frame levelled by its walls (levelling_rotation over the session's
// submaps), so that it is projected along gravity rather than along the first scan's lean; not for
// a run in local ENU (GNSS) nor without a session.
// From the scans when `input` is not empty, else from the session's submap clouds (rays from the
// nearest keyframe of the submap). progress(done, total) over both passes.
GridResult make_grid(const std::string& out, const std::string& input, const GridOptions& options,
                     const std::function<void(size_t, size_t)>& progress);

}  // namespace gcmap::cli
