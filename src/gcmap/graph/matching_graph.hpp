#pragma once
#include <memory>
#include <vector>

#include "gcmap/graph/backend.hpp"
#include "gcmap/registration/registration.hpp"

namespace gcmap {

struct ScanNode {
  std::shared_ptr<const PointCloud> cloud;  // with covariances
  std::shared_ptr<const GaussianVoxelMap> voxels;
};

// Estimates the cloud's covariances and builds its voxel map.
ScanNode make_scan_node(PointCloud cloud, double voxel_resolution);

// VGICP of one pair on a backend: align_vgicp on the CPU; elsewhere the same cost as a two-pose
// graph (target fixed) through LM, so a GPU linearizes it.
RegistrationResult align_vgicp_on(const std::shared_ptr<LinearizationBackend>& backend, const std::shared_ptr<const PointCloud>& source,
                                  const std::shared_ptr<const GaussianVoxelMap>& target, const Eigen::Isometry3d& init,
                                  int max_iterations);

struct PairOverlap {
  int source, target;
  double overlap;  // overlap(source -> target) at the given poses
};

// For every pair i < j whose overlap(j -> i) at the poses is at least min_overlap, adds a
// MatchingCostFactor with source j and target i. Returns the pairs that got a factor. Overlaps are
// computed by the backend (the CPU when null), one source against all its targets at a time.
std::vector<PairOverlap> add_overlapping_pairs(FactorGraph& graph, const std::vector<ScanNode>& nodes,
                                               const Values& values, double min_overlap,
                                               LinearizationBackend* backend = nullptr);

}  // namespace gcmap
