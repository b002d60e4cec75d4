#include "gcmap/odometry/preprocess_scan.hpp"

#include <cmath>

#include "gcmap/core/preprocess.hpp"

namespace gcmap {

PointCloud preprocess_scan(const PointCloud& raw, const PreprocessConfig& config, LinearizationBackend* backend) {
  PointCloud c = voxel_downsample(range_filter(raw, config.min_range, config.max_range), config.downsample);
  CovarianceConfig cc;
  cc.num_neighbors = config.num_neighbors;
  cc.epsilon = config.plane_epsilon;
  cc.elevation_sigma = config.elevation_sigma_deg * M_PI / 180.0;
  if (backend) backend->estimate_covariances(c, cc);
  else estimate_covariances(c, cc);
  return c;
}

}  // namespace gcmap
