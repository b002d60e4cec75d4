#pragma once
// Small synthetic scenes with exact geometry for tests and benchmarks (no sensor model).
#include <cstdint>

#include "gcmap/core/point_cloud.hpp"

namespace gcmap {

// Points sampled on a structured scene around the origin: a ground plane, walls of several
// orientations, boxes, a sphere and cylinders, within about `extent` metres. Deterministic in seed.
PointCloud make_structured_scene(size_t num_points, uint64_t seed, double extent = 20.0);

// What a sensor at the origin sees of a straight tunnel along x (walls at y = +-5, floor at z = -2,
// roof at z = 4, nothing that tells one x from another) within max_range: rays at random azimuths
// and elevations (+-30 deg), so the points thin out with range as a LiDAR's do; 1 cm range noise.
// Deterministic in seed.
PointCloud make_tunnel_scan(size_t num_points, uint64_t seed, double max_range);

}  // namespace gcmap
