#include "gcmap/graph/backend.hpp"

#include <tbb/parallel_for.h>

#include "gcmap/core/error.hpp"

namespace gcmap {

Device parse_device(const std::string& text, const std::string& key) {
  if (text == "cpu") return Device::cpu;
  if (text == "cuda") return Device::cuda;
  if (text == "auto") return Device::automatic;
  throw Error(key + ": expected cpu, cuda or auto, got '" + text + "'");
}

const char* device_name(Device device) {
  switch (device) {
    case Device::cpu: return "cpu";
    case Device::cuda: return "cuda";
    case Device::automatic: return "auto";
  }
  return "?";
}

void LinearizationBackend::estimate_covariances(PointCloud& cloud, const CovarianceConfig& config) {
  gcmap::estimate_covariances(cloud, config);
}

void LinearizationBackend::overlaps(const std::shared_ptr<const PointCloud>& source,
                                    std::span<const std::shared_ptr<const GaussianVoxelMap>> targets,
                                    std::span<const Eigen::Isometry3d> T_target_source, std::span<double> out) {
  tbb::parallel_for(size_t{0}, targets.size(), [&](size_t k) { out[k] = overlap(*source, *targets[k], T_target_source[k]); });
}

void CpuBackend::linearize(std::span<Factor* const> factors, std::span<const FactorPoses> poses,
                           std::span<FactorLinearization> out) {
  tbb::parallel_for(size_t{0}, factors.size(), [&](size_t f) { factors[f]->linearize(poses[f].data(), out[f]); });
}

void CpuBackend::trial_errors(std::span<Factor* const> factors, std::span<const FactorPoses> poses, std::span<double> out) {
  tbb::parallel_for(size_t{0}, factors.size(), [&](size_t f) { out[f] = factors[f]->trial_error(poses[f].data()); });
}

std::vector<TargetOverlap> overlapping_targets(LinearizationBackend& backend, const std::shared_ptr<const PointCloud>& source,
                                               std::span<const std::shared_ptr<const GaussianVoxelMap>> targets,
                                               std::span<const Eigen::Isometry3d> T_target_source, double min_overlap) {
  // Most submaps of a long drive lie out of reach of a new one: their boxes say so without a lookup.
  const Eigen::AlignedBox3f source_box = bounding_box(*source);
  std::vector<int> reach;
  std::vector<std::shared_ptr<const GaussianVoxelMap>> reach_targets;
  std::vector<Eigen::Isometry3d> reach_T;
  for (size_t k = 0; k < targets.size(); ++k) {
    if (min_overlap > 0.0 && !may_overlap(source_box, *targets[k], T_target_source[k])) continue;
    reach.push_back(static_cast<int>(k));
    reach_targets.push_back(targets[k]);
    reach_T.push_back(T_target_source[k]);
  }
  std::vector<double> overlaps(reach.size());
  backend.overlaps(source, reach_targets, reach_T, overlaps);
  std::vector<TargetOverlap> kept;
  for (size_t r = 0; r < reach.size(); ++r)
    if (overlaps[r] >= min_overlap) kept.push_back({reach[r], overlaps[r]});
  return kept;
}

RegistrationResult LinearizationBackend::align(const PointCloud& source, const std::shared_ptr<const GaussianVoxelMap>& target,
                                               const Eigen::Isometry3d& init_T_target_source, const RegistrationConfig& config) {
  return align_vgicp(source, *target, init_T_target_source, config);
}

}  // namespace gcmap
