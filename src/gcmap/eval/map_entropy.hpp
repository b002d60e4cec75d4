#pragma once
#include <functional>

#include "gcmap/core/point_cloud.hpp"

namespace gcmap {

// Mean map entropy (Razlaw et al. 2015): per point, the entropy 0.5 * ln det(2 pi e Sigma) of the
// Gaussian of its neighbours within `radius`, averaged over points with at least min_neighbors.
struct MapEntropy {
  double mean = 0.0;
  double stddev = 0.0;
  size_t num_points = 0;   // points that contributed
  size_t num_skipped = 0;  // too few neighbours or degenerate covariance
};
// progress(points done, points in all), for a person: from one worker thread at a time.
using EntropyProgress = std::function<void(size_t done, size_t total)>;
MapEntropy mean_map_entropy(const PointCloud& map, double radius = 0.3, int min_neighbors = 15,
                            const EntropyProgress& progress = {});

}  // namespace gcmap
