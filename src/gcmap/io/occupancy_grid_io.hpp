#pragma once
// 2D occupancy grids as ROS map_server / Nav2 map_server read them: a P5 PGM image and a YAML file
// with image, mode, resolution, origin [x, y, yaw], negate, occupied_thresh and free_thresh.
// Pixels follow map_saver's trinary convention: occupied 0 (dark), free 254 (light), unknown 205.
#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

namespace gcmap {

enum class Occupancy : uint8_t { unknown, free, occupied };

struct OccupancyGrid {
  int width = 0, height = 0;
  double resolution = 0.05;                          // m per cell
  Eigen::Vector2d origin = Eigen::Vector2d::Zero();  // map-frame corner of cell (0, 0), the lower left
  std::vector<Occupancy> cells;                      // row-major, row 0 at the lowest y (map_server's origin row)

  Occupancy at(int x, int y) const { return cells[static_cast<size_t>(y) * width + x]; }
  // The cell holding map-frame point (x, y); false outside the grid.
  bool cell_of(double x, double y, int& cx, int& cy) const;
  size_t count(Occupancy state) const;
};

// Writes DIR/STEM.pgm and DIR/STEM.yaml atomically (the YAML names the image relative to itself).
void write_map_server(const std::string& dir, const std::string& stem, const OccupancyGrid& grid);
// Reads a map.yaml of trinary mode and its image (P5 PGM, 8 bit) with map_server's thresholds;
// throws Error("PATH: ...") for a missing key, another mode, a rotated origin or a malformed image.
OccupancyGrid read_map_server(const std::string& yaml_path);

}  // namespace gcmap
