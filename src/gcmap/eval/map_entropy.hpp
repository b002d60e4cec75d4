#pragma once
#include "gcmap/core/point_cloud.hpp"

namespace gcmap {

// Mean map entropy (Razlaw et al. 2015): per point, the entropy 0.5 * ln det(2 pi e Sigma) of the
// Gaussian of its neighbours within `radius`, averaged over points with at least min_neighbors.
struct MapEntropy {
  double mean = 0.0;
  double stddev = 0.0;
  size_t num_points = 0;     // points that contributed
  size_t num_skipped = 0;    // too few neighbours or degenerate covariance
};
MapEntropy mean_map_entropy(const PointCloud& map, double radius = 0.3, int min_neighbors = 15);

}  // namespace gcmap
