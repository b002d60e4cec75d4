#pragma once
// An occupancy grid against the simulator's world: the true walls rasterized at the grid's cells.
#include <tbb/parallel_for.h>

#include <cmath>
#include <cstdlib>
#include <string>

#include "gcmap/io/occupancy_grid_io.hpp"
#include "gcmap/sim/simulator.hpp"

namespace gcmap::test {

struct GridScore {
  double iou = 0.0;               // occupied cells vs the observed true walls, one cell of tolerance
  double occupied_on_wall = 0.0;  // share of occupied cells within one cell of a true wall
  size_t walls = 0, occupied = 0, free = 0;
  size_t free_inside = 0;  // free cells inside solid objects (all 8 neighbours solid)
  size_t free_deep = 0;    // free cells 1 m or more inside: in buildings (cars, canopies are thinner)
};

// Solid columns over the grid's cells: a static object within [band_min, band_max] above the
// ground. The map frame is the first scan's sensor frame: sim.poses()[0] in the world; the grid's
// frame is that turned by R_level_map (export.json).
inline std::vector<char> solid_cells(const OccupancyGrid& g, const sim::Simulator& sim, float band_min, float band_max,
                                     const Eigen::Matrix3d& R_level_map) {
  Eigen::Isometry3d T_map_level = Eigen::Isometry3d::Identity();
  T_map_level.linear() = R_level_map.transpose();
  const Eigen::Isometry3d T_world_map = sim.poses()[0] * T_map_level;
  std::vector<char> solid(g.cells.size(), 0);
  tbb::parallel_for(0, g.height, [&](int y) {
    for (int x = 0; x < g.width; ++x) {
      // Half a metre below the sensor: the band's middle, where a tilt of the map frame moves least.
      const Eigen::Vector3d p_map(g.origin.x() + (x + 0.5) * g.resolution, g.origin.y() + (y + 0.5) * g.resolution, -0.5);
      const Eigen::Vector3d w = T_world_map * p_map;
      const float ground = sim.world().ground_height(static_cast<float>(w.x()), static_cast<float>(w.y()));
      solid[static_cast<size_t>(y) * g.width + x] =
          sim.world().column_solid(static_cast<float>(w.x()), static_cast<float>(w.y()), ground + band_min, ground + band_max);
    }
  });
  return solid;
}

// R_level_map of an export's export.json (row major after the key).
inline Eigen::Matrix3d level_of(const std::string& export_json) {
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  size_t at = export_json.find("\"R_level_map\":[");
  if (at == std::string::npos) return R;
  const char* p = export_json.c_str() + at + 15;
  for (int i = 0; i < 9; ++i) {
    char* end = nullptr;
    R(i / 3, i % 3) = std::strtod(p, &end);
    p = end + 1;
  }
  return R;
}

// Cells with any of their 3 x 3 block set.
inline std::vector<char> dilated(const std::vector<char>& m, int w, int h) {
  std::vector<char> d(m.size(), 0);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int v = std::max(0, y - 1); v <= std::min(h - 1, y + 1) && !d[y * w + x]; ++v)
        for (int u = std::max(0, x - 1); u <= std::min(w - 1, x + 1); ++u)
          if (m[v * w + u]) d[y * w + x] = 1;
  return d;
}

// Cells whose whole 3 x 3 block is set.
inline std::vector<char> eroded(const std::vector<char>& m, int w, int h) {
  std::vector<char> e(m.size(), 0);
  for (int y = 1; y + 1 < h; ++y)
    for (int x = 1; x + 1 < w; ++x) {
      bool all = true;
      for (int v = y - 1; v <= y + 1 && all; ++v)
        for (int u = x - 1; u <= x + 1; ++u) all = all && m[v * w + u];
      e[y * w + x] = all;
    }
  return e;
}

// True walls: solid cells beside a non-solid one, where the grid knows a cell within one cell
// (walls no ray could reach, behind buildings, are not held against it).
inline GridScore score_grid(const OccupancyGrid& g, const sim::Simulator& sim, float band_min, float band_max,
                            const Eigen::Matrix3d& R_level_map) {
  const int w = g.width, h = g.height;
  const std::vector<char> solid = solid_cells(g, sim, band_min, band_max, R_level_map);
  std::vector<char> known(solid.size()), occupied(solid.size()), wall(solid.size(), 0);
  for (size_t i = 0; i < solid.size(); ++i)
    known[i] = g.cells[i] != Occupancy::unknown, occupied[i] = g.cells[i] == Occupancy::occupied;
  const std::vector<char> near_known = dilated(known, w, h);
  GridScore s;
  for (int y = 1; y + 1 < h; ++y)
    for (int x = 1; x + 1 < w; ++x) {
      const size_t i = static_cast<size_t>(y) * w + x;
      const int around = solid[i - 1] + solid[i + 1] + solid[i - w] + solid[i + w];
      const int all8 = around + solid[i - w - 1] + solid[i - w + 1] + solid[i + w - 1] + solid[i + w + 1];
      wall[i] = solid[i] && around < 4 && near_known[i];
      s.free_inside += solid[i] && all8 == 8 && g.cells[i] == Occupancy::free;
    }
  std::vector<char> deep = solid;
  for (int k = 0; k < static_cast<int>(std::ceil(1.0 / g.resolution)); ++k) deep = eroded(deep, w, h);
  for (size_t i = 0; i < solid.size(); ++i) s.free_deep += deep[i] && g.cells[i] == Occupancy::free;
  const std::vector<char> dw = dilated(wall, w, h), dov = dilated(occupied, w, h);
  size_t inter = 0, uni = 0, on_wall = 0;
  for (size_t i = 0; i < solid.size(); ++i) {
    inter += dw[i] && dov[i], uni += dw[i] || dov[i], on_wall += occupied[i] && dw[i];
    s.walls += wall[i], s.occupied += occupied[i], s.free += g.cells[i] == Occupancy::free;
  }
  s.iou = uni ? static_cast<double>(inter) / uni : 0.0;
  s.occupied_on_wall = s.occupied ? static_cast<double>(on_wall) / s.occupied : 0.0;
  return s;
}

}  // namespace gcmap::test
