#include "gcmap/graph/matching_graph.hpp"

#include "gcmap/core/preprocess.hpp"
#include "gcmap/graph/levenberg_marquardt.hpp"
#include "gcmap/registration/vgicp.hpp"

namespace gcmap {

ScanNode make_scan_node(PointCloud cloud, double voxel_resolution) {
  estimate_covariances(cloud);
  auto voxels = std::make_shared<GaussianVoxelMap>(voxel_resolution);
  voxels->insert(cloud);
  voxels->finalize();
  return {std::make_shared<const PointCloud>(std::move(cloud)), voxels};
}

RegistrationResult align_vgicp_on(const std::shared_ptr<LinearizationBackend>& backend, const std::shared_ptr<const PointCloud>& source,
                                  const std::shared_ptr<const GaussianVoxelMap>& target, const Eigen::Isometry3d& init,
                                  int max_iterations) {
  if (backend->device() == Device::cpu) {
    RegistrationConfig config;
    config.max_iterations = max_iterations;
    return align_vgicp(*source, *target, init, config);
  }
  FactorGraph graph;
  graph.add(std::make_shared<MatchingCostFactor>(1, 0, source, target));
  Values values{{0, Eigen::Isometry3d::Identity()}, {1, init}};
  LMConfig config;
  config.max_iterations = max_iterations;
  const LMResult lm = LevenbergMarquardt(config, backend).optimize(graph, values, {0});
  RegistrationResult r;
  r.T_target_source = values.at(1);
  r.converged = lm.converged;
  r.iterations = lm.iterations;
  const VgicpError e = evaluate_vgicp(*source, *target, r.T_target_source);
  r.error = e.error;
  r.num_inliers = e.num_inliers;
  return r;
}

std::vector<PairOverlap> add_overlapping_pairs(FactorGraph& graph, const std::vector<ScanNode>& nodes,
                                               const Values& values, double min_overlap, LinearizationBackend* backend) {
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
