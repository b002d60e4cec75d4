#include "gcmap/graph/matching_graph.hpp"

#include "gcmap/core/preprocess.hpp"

namespace gcmap {

ScanNode make_scan_node(PointCloud cloud, double voxel_resolution) {
  estimate_covariances(cloud);
  auto voxels = std::make_shared<GaussianVoxelMap>(voxel_resolution);
  voxels->insert(cloud);
  voxels->finalize();
  return {std::make_shared<const PointCloud>(std::move(cloud)), voxels};
}

std::vector<PairOverlap> add_overlapping_pairs(FactorGraph& graph, const std::vector<ScanNode>& nodes, const Values& values,
                                               double min_overlap, LinearizationBackend* backend) {
  CpuBackend cpu;
  if (!backend) backend = &cpu;
  std::vector<PairOverlap> kept;
  for (int j = 1; j < static_cast<int>(nodes.size()); ++j) {
    std::vector<std::shared_ptr<const GaussianVoxelMap>> targets;
    std::vector<Eigen::Isometry3d> T_target_source;
    for (int i = 0; i < j; ++i) {
      targets.push_back(nodes[i].voxels);
      T_target_source.push_back(values.at(i).inverse() * values.at(j));
    }
    for (const TargetOverlap& t : overlapping_targets(*backend, nodes[j].cloud, targets, T_target_source, min_overlap)) {
      graph.add(std::make_shared<MatchingCostFactor>(j, t.index, nodes[j].cloud, nodes[t.index].voxels));
      kept.push_back({j, t.index, t.overlap});
    }
  }
  return kept;
}

}  // namespace gcmap
