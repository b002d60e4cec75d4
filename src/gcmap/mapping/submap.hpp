#pragma once
// A submap: keyframes optimized together and merged into one cloud (paper Section III-A).
#include <memory>
#include <optional>
#include <vector>

#include "gcmap/core/gaussian_voxel_map.hpp"
#include "gcmap/loop/scan_context.hpp"

namespace gcmap {

struct Submap {
  int id = 0;
  std::vector<int> keyframes;                                // frame indices
  std::vector<Eigen::Isometry3d> T_submap_keyframe;          // fixed after the local optimization
  std::vector<ScanContext> descriptors;                      // per keyframe, when explicit loops are on
  Eigen::Isometry3d T_odom = Eigen::Isometry3d::Identity();  // odometry pose of the submap origin
  std::shared_ptr<const PointCloud> cloud;                   // merged, in the submap frame
  std::shared_ptr<const PointCloud> factor_source;           // subsample of cloud: source of its factors
  std::shared_ptr<const GaussianVoxelMap> voxels;            // at global.voxel_resolution
  // m: how much its keyframes disagree at their optimum (SubmapBuilder), the noise its own data
  // shows; absent for one keyframe, and in submaps loaded from a session (not stored there).
  std::optional<float> keyframe_noise;
};

// At most n points, by an even stride: deterministic and spatially uniform (points are in voxel order).
PointCloud evenly_subsampled(PointCloud cloud, int n);

}  // namespace gcmap
