#pragma once
#include "gcmap/core/point_cloud.hpp"
#include "gcmap/graph/backend.hpp"
#include "gcmap/mapping/config.hpp"

namespace gcmap {

// Range filter, voxel downsampling and k-neighbour covariances of one raw scan; the covariances on
// `backend` when given (a GPU's), else on the CPU.
PointCloud preprocess_scan(const PointCloud& raw, const PreprocessConfig& config, LinearizationBackend* backend = nullptr);

}  // namespace gcmap
