#include "gcmap/graph/factor_graph.hpp"

#include <tbb/parallel_for.h>

#include "gcmap/core/error.hpp"

namespace gcmap {

void FactorGraph::add(std::shared_ptr<Factor> factor) {
  if (factor->num_keys() == 2 && factor->keys()[0] == factor->keys()[1])
    throw Error("a factor cannot connect pose " + std::to_string(factor->keys()[0]) + " to itself");
  factors.push_back(std::move(factor));
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

void CpuBackend::trial_errors(std::span<Factor* const> factors, std::span<const FactorPoses> poses,
                              std::span<double> out) {
  tbb::parallel_for(size_t{0}, factors.size(), [&](size_t f) { out[f] = factors[f]->trial_error(poses[f].data()); });
}

}  // namespace gcmap
