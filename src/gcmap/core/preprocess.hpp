#pragma once
#include "gcmap/core/point_cloud.hpp"

namespace gcmap {

// Averages the points (and every channel present) of each occupied voxel. Deterministic for any
// thread count: voxels come out in lexicographic voxel-coordinate order. Voxel coordinates are
// computed in double and kept as 64-bit integers, so +-100 km at 5 cm is exact.
PointCloud voxel_downsample(const PointCloud& cloud, double resolution);

// Keeps points whose distance to the origin lies in [min_range, max_range].
PointCloud range_filter(const PointCloud& cloud, double min_range, double max_range);

// Drops points with a non-finite coordinate; returns how many were dropped.
size_t remove_non_finite(PointCloud& cloud);

struct CovarianceConfig {
  int num_neighbors = 10;
  // Plane-like regularization (VGICP/GLIM): eigenvalues replaced by (epsilon, 1, 1).
  double epsilon = 1e-3;
  // Beam elevation uncertainty (rad), for points still in the sensor frame: adds (range *
  // sigma)^2 along the direction a change of elevation moves the point.
  double elevation_sigma = 0.0;
};

// Per-point covariance from the k nearest neighbours, regularized plane-like. Points with fewer than
// 4 neighbours (tiny clouds) get an isotropic covariance instead of a degenerate one.
void estimate_covariances(PointCloud& cloud, const CovarianceConfig& config = {});

}  // namespace gcmap
