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

struct PairOverlap {
  int source, target;
  double overlap;  // overlap(source -> target) at the given poses
};

// For every pair i < j whose overlap(j -> i) at the poses is at least min_overlap, adds a
// MatchingCostFactor with source j and target i. Returns the pairs that got a factor. Overlaps are
// computed by the backend (the CPU when null), one source against all its targets at a time.
std::vector<PairOverlap> add_overlapping_pairs(FactorGraph& graph, const std::vector<ScanNode>& nodes, const Values& values,
                                               double min_overlap, LinearizationBackend* backend = nullptr);

}  // namespace gcmap
