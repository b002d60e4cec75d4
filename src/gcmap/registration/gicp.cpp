#include "gcmap/registration/gicp.hpp"

#include <tbb/parallel_for.h>

#include "gcmap/core/error.hpp"
#include "gcmap/registration/gaussian_terms.hpp"

namespace gcmap {

GicpTarget::GicpTarget(std::shared_ptr<const PointCloud> cloud) : cloud_(std::move(cloud)), tree_(cloud_->points) {
  if (cloud_->covs.size() != cloud_->size()) throw Error("GicpTarget: the target cloud has no covariances");
}

std::vector<int> find_correspondences(const PointCloud& source, const GicpTarget& target,
                                      const Eigen::Isometry3d& T_target_source, double max_distance) {
  std::vector<int> out(source.size(), -1);
  if (target.cloud().empty()) return out;
  const PointTransform X(T_target_source);
  const float max_sq = static_cast<float>(max_distance * max_distance);
  tbb::parallel_for(tbb::blocked_range<size_t>(0, source.size(), 256), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i != r.end(); ++i) {
      uint32_t index = 0;
      float sq = 0.f;
      if (target.tree().knn(X * source.points[i], 1, &index, &sq) == 1 && sq <= max_sq) out[i] = static_cast<int>(index);
    }
  });
  return out;
}

VgicpLinearization linearize_gicp(const PointCloud& source, const GicpTarget& target, const Eigen::Isometry3d& T_target_source,
                                  const std::vector<int>& correspondences) {
  const TargetFrameSums sums = detail::accumulate_target_frame(
      source, target.cloud(), T_target_source, [&](size_t i, const Eigen::Vector3f&) { return correspondences[i]; });
  return expand_to_both_poses(sums, T_target_source);
}

VgicpError evaluate_gicp(const PointCloud& source, const GicpTarget& target, const Eigen::Isometry3d& T_target_source,
                         const std::vector<int>& correspondences) {
  return detail::sum_errors(source, target.cloud(), T_target_source,
                            [&](size_t i, const Eigen::Vector3f&) { return correspondences[i]; });
}

}  // namespace gcmap
