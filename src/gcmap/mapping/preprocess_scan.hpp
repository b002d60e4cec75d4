#pragma once
#include "gcmap/core/point_cloud.hpp"
#include "gcmap/mapping/config.hpp"

namespace gcmap {

// Range filter, voxel downsampling and k-neighbour covariances of one raw scan.
PointCloud preprocess_scan(const PointCloud& raw, const PreprocessConfig& config);

}  // namespace gcmap
