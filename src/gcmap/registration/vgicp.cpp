#include "gcmap/registration/vgicp.hpp"

#include <Eigen/Eigenvalues>

#include "gcmap/core/error.hpp"
#include "gcmap/registration/gaussian_terms.hpp"
#include "gcmap/registration/registration.hpp"

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

bool drop_weak_translation(TargetFrameSums& sums, double min_conditioning) {
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(translation_information(sums.H));
  const Eigen::Vector3d e = eig.eigenvalues().cwiseMax(0.0);
  if (!(e[2] > 0.0) || e[0] >= min_conditioning * e[2]) return false;
  // d -> P d with P removing the translation along the weakest direction: the cost no longer
  // changes along it, whatever the rotation.
  Matrix6d P = Matrix6d::Identity();
  P.bottomRightCorner<3, 3>() -= eig.eigenvectors().col(0) * eig.eigenvectors().col(0).transpose();
  sums.H = P * sums.H * P;
  sums.b = P * sums.b;
  return true;
}

namespace {
float squared(float robust_width) { return robust_width > 0.f ? robust_width * robust_width : 0.f; }
}  // namespace

VgicpLinearization linearize_vgicp(const PointCloud& source, const GaussianVoxelMap& target,
                                   const Eigen::Isometry3d& T_target_source, float robust_width) {
  const TargetFrameSums sums = detail::accumulate_target_frame(
      source, target, T_target_source, [&](size_t, const Eigen::Vector3f& q) { return target.lookup(q); }, squared(robust_width));
  return expand_to_both_poses(sums, T_target_source);
}

VgicpLinearization linearize_vgicp(const PointCloud& source, const GaussianVoxelMap& target,
                                   const Eigen::Isometry3d& T_target_source, std::vector<int>& associations, float robust_width) {
  associations.resize(source.size());
  const TargetFrameSums sums = detail::accumulate_target_frame(
      source, target, T_target_source,
      [&](size_t i, const Eigen::Vector3f& q) {
        return associations[i] = target.lookup(q);  // distinct i per task
      },
      squared(robust_width));
  return expand_to_both_poses(sums, T_target_source);
}

VgicpError evaluate_vgicp(const PointCloud& source, const GaussianVoxelMap& target, const Eigen::Isometry3d& T_target_source,
                          std::span<const int> associations, float robust_width) {
  if (associations.size() != source.size()) throw Error("evaluate_vgicp: associations do not match the source");
  return detail::sum_errors(
      source, target, T_target_source, [&](size_t i, const Eigen::Vector3f&) { return associations[i]; }, squared(robust_width));
}

VgicpError evaluate_vgicp(const PointCloud& source, const GaussianVoxelMap& target, const Eigen::Isometry3d& T_target_source) {
  return detail::sum_errors(source, target, T_target_source, [&](size_t, const Eigen::Vector3f& q) { return target.lookup(q); });
}

VgicpError evaluate_vgicp(const PointCloud& source, const GaussianVoxelMap& target, const Eigen::Isometry3d& T_target_source,
                          const Eigen::Isometry3d& T_association, float robust_width) {
  const PointTransform A(T_association);
  return detail::sum_errors(
      source, target, T_target_source, [&](size_t i, const Eigen::Vector3f&) { return target.lookup(A * source.points[i]); },
      squared(robust_width));
}

}  // namespace gcmap
