#pragma once
// A 2D occupancy grid for navigation (Nav2, ROS map_server) made by casting every scan's rays.
//
// Model: each ray runs from the sensor's position at the point's time to the point, in the map
// frame. Heights are taken above the local ground: the lowest return within about 1.5 m (a 3 x 3
// block of 1 m columns) that two more returns of its own scan confirm within 0.25 m, so hills, a
// map frame tilted with the first scan and stray echoes beyond the ground do not turn the ground
// into walls. A return whose height lies in the band [height_min, height_max] marks its cell
// hit; the cells the ray crosses while it is no higher than height_max (and the end cell of a ray
// that reached the ground below the band) are passed. Evidence is counted once per scan and cell,
// a hit winning over a pass in the same scan (thin walls grazed by neighbouring rays). A cell is
// occupied when hit in min_scans scans and hits >= occupied_ratio * (hits + passes), free when
// passed in min_scans scans and not occupied, else unknown: one scan's stray echo, whose ray runs
// through a wall into a building, is no evidence. Moving objects are hit in a few scans and passed
// in many: free.
#include <Eigen/Geometry>
#include <atomic>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "gcmap/io/occupancy_grid_io.hpp"

namespace gcmap {

struct GridOptions {
  double resolution = 0.05;                    // m per cell
  float height_min = 0.3f, height_max = 2.0f;  // the obstacle band, m above the local ground
  float max_range = 40.f;                      // m in the plane; farther returns are not used
  float min_range = 1.0f;                      // m in the plane; nearer returns are the vehicle itself
  float occupied_ratio = 0.25f;
  uint16_t min_scans = 2;    // scans that must agree before a cell is occupied or free
  float ground_cell = 1.0f;  // m: columns of the local ground
};

// The rays of one scan or submap (a view): end points in the map frame and the origin of each.
struct RayBatch {
  std::span<const Eigen::Vector3f> ends;
  std::span<const uint16_t> origin_of;  // per end: index into origins
  std::span<const Eigen::Vector3f> origins;
};

// Two passes over the same batches: add_ground for all, then finish_ground, then add_rays for all.
// add_ground and add_rays may run concurrently on different batches; they do not allocate once
// each thread's scratch has grown to a scan's window.
class OccupancyGridBuilder {
 public:
  // bounds: the map-frame area that can hold rays (the origins' extent grown by max_range). Throws
  // Error naming --grid-resolution when the grid would not fit in memory.
  OccupancyGridBuilder(const Eigen::AlignedBox2d& bounds, const GridOptions& options);
  ~OccupancyGridBuilder();
  void add_ground(const RayBatch& batch);
  void finish_ground();
  void add_rays(const RayBatch& batch);
  // The grid cropped to its known cells (one unknown cell around them).
  OccupancyGrid grid() const;

 private:
  struct Scratch;
  struct Cell {
    uint16_t hits = 0, passes = 0;
  };
  bool usable(const RayBatch& b, size_t i, float& height_above, float& ground) const;
  void cast(const Eigen::Vector3f& o, const Eigen::Vector3f& p, float ground, bool hit, Scratch& s) const;
  void visit(int cx, int cy, Scratch& s) const;
  Occupancy state(const Cell& c) const;

  GridOptions o_;
  int64_t x0_ = 0, y0_ = 0;  // grid origin in cells
  int width_ = 0, height_ = 0;
  mutable std::vector<Cell> cells_;
  int gw_ = 0, gh_ = 0;  // ground columns
  std::vector<float> ground_min_, ground_;
  std::atomic<uint32_t> next_scan_{1};
  struct ScratchPool;
  std::unique_ptr<ScratchPool> scratch_;
};

}  // namespace gcmap
