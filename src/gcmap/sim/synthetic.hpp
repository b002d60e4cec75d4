#pragma once
// Small synthetic scenes with exact geometry for tests and benchmarks (no sensor model).
#include <cstdint>

#include "gcmap/core/point_cloud.hpp"

namespace gcmap {

// Points sampled on a structured scene around the origin: a ground plane, walls of several
// orientations, boxes, a sphere and cylinders, within about `extent` metres. Deterministic in seed.
PointCloud make_structured_scene(size_t num_points, uint64_t seed, double extent = 20.0);

}  // namespace gcmap
