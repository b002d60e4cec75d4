#include "gcmap/registration/vgicp.hpp"

#include "gcmap/core/error.hpp"
#include "gcmap/registration/gaussian_terms.hpp"

namespace gcmap {

VgicpLinearization expand_to_both_poses(const TargetFrameSums& sums, const Eigen::Isometry3d& T) {
  const Matrix6d M = adjoint(T);
  VgicpLinearization out;
  out.H_jj = sums.H;
  out.b_j = sums.b;
  out.H_ij = -M.transpose() * sums.H;
  out.H_ii = -out.H_ij * M;
  out.b_i = -M.transpose() * sums.b;
  out.error = sums.error;
  out.num_inliers = sums.num_inliers;
  return out;
}

VgicpLinearization linearize_vgicp(const PointCloud& source, const GaussianVoxelMap& target,
                                   const Eigen::Isometry3d& T_target_source) {
  const TargetFrameSums sums = detail::accumulate_target_frame(
      source, target, T_target_source, [&](size_t, const Eigen::Vector3f& q) { return target.lookup(q); });
  return expand_to_both_poses(sums, T_target_source);
}

VgicpLinearization linearize_vgicp(const PointCloud& source, const GaussianVoxelMap& target,
                                   const Eigen::Isometry3d& T_target_source, std::vector<int>& associations) {
  associations.resize(source.size());
  const TargetFrameSums sums =
      detail::accumulate_target_frame(source, target, T_target_source, [&](size_t i, const Eigen::Vector3f& q) {
        return associations[i] = target.lookup(q);  // distinct i per task
      });
  return expand_to_both_poses(sums, T_target_source);
}

VgicpError evaluate_vgicp(const PointCloud& source, const GaussianVoxelMap& target, const Eigen::Isometry3d& T_target_source,
                          std::span<const int> associations) {
  if (associations.size() != source.size()) throw Error("evaluate_vgicp: associations do not match the source");
  return detail::sum_errors(source, target, T_target_source, [&](size_t i, const Eigen::Vector3f&) { return associations[i]; });
}

VgicpError evaluate_vgicp(const PointCloud& source, const GaussianVoxelMap& target, const Eigen::Isometry3d& T_target_source) {
  return detail::sum_errors(source, target, T_target_source, [&](size_t, const Eigen::Vector3f& q) { return target.lookup(q); });
}

VgicpError evaluate_vgicp(const PointCloud& source, const GaussianVoxelMap& target, const Eigen::Isometry3d& T_target_source,
                          const Eigen::Isometry3d& T_association) {
  const PointTransform A(T_association);
  return detail::sum_errors(source, target, T_target_source,
                            [&](size_t i, const Eigen::Vector3f&) { return target.lookup(A * source.points[i]); });
}

}  // namespace gcmap
