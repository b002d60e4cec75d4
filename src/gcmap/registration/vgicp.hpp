#pragma once
// VGICP matching cost between a source cloud i and a target Gaussian voxel map j
// (shared/docs/vgicp-factor-math.md). T_target_source = T_j^-1 T_i maps source points into the
// target frame; per inlier point, e = mu' - T mu, Omega = (C' + R C R^T)^-1, cost e^T Omega e.
#include <span>
#include <vector>

#include "gcmap/core/gaussian_voxel_map.hpp"
#include "gcmap/core/point_cloud.hpp"
#include "gcmap/core/se3.hpp"

namespace gcmap {

// Gauss-Newton blocks of the cost w.r.t. right perturbations of T_i (source) and T_j (target):
// f(d) ~ error + 2 b^T d + d^T H d with d = [d_i; d_j].
struct VgicpLinearization {
  Matrix6d H_ii = Matrix6d::Zero();
  Matrix6d H_ij = Matrix6d::Zero();
  Matrix6d H_jj = Matrix6d::Zero();
  Vector6d b_i = Vector6d::Zero();
  Vector6d b_j = Vector6d::Zero();
  double error = 0.0;
  size_t num_inliers = 0;
};

struct VgicpError {
  double error = 0.0;
  size_t num_inliers = 0;
};

// Data association (voxel lookup) and Omega are recomputed from T_target_source on every call.
// Parallel over points with a deterministic reduction: the same result for any thread count.
// robust_width c > 0: each point's cost is Cauchy's, c^2 log(1 + m2 / c^2) with m2 = e^T Omega e its
// squared Mahalanobis distance, linearized with Omega weighted by c^2 / (c^2 + m2) (IRLS); errors are
// that cost. Points many sigmas off their voxel (a thin object seen from its other side, a voxel
// holding two surfaces) pull less.
VgicpLinearization linearize_vgicp(const PointCloud& source, const GaussianVoxelMap& target,
                                   const Eigen::Isometry3d& T_target_source, float robust_width = 0.f);
VgicpError evaluate_vgicp(const PointCloud& source, const GaussianVoxelMap& target, const Eigen::Isometry3d& T_target_source);

// Error at T_target_source with each point associated to the voxel it falls in under T_association
// (the linearization point). LM judges trial steps with this: re-associating at a trial pose adds
// newly matched points to the sum, so a better alignment can show a larger error and LM would stall.
VgicpError evaluate_vgicp(const PointCloud& source, const GaussianVoxelMap& target, const Eigen::Isometry3d& T_target_source,
                          const Eigen::Isometry3d& T_association, float robust_width = 0.f);

// The same pair for a caller that can keep 4 bytes per source point (one registration; the global
// graph's thousands of factors cannot): the linearization records each point's voxel (-1: none),
// and the evaluation reuses it instead of transforming and looking up again. Same results.
VgicpLinearization linearize_vgicp(const PointCloud& source, const GaussianVoxelMap& target,
                                   const Eigen::Isometry3d& T_target_source, std::vector<int>& associations,
                                   float robust_width = 0.f);
VgicpError evaluate_vgicp(const PointCloud& source, const GaussianVoxelMap& target, const Eigen::Isometry3d& T_target_source,
                          std::span<const int> associations, float robust_width = 0.f);

// The accumulation is done in the target frame (B = de/dd_j = [-[q]x, I]); the source blocks follow
// exactly from A = -B Ad(T_target_source), so a binary factor costs no more than a unary one.
struct TargetFrameSums {
  Matrix6d H = Matrix6d::Zero();
  Vector6d b = Vector6d::Zero();
  double error = 0.0;
  size_t num_inliers = 0;
};
VgicpLinearization expand_to_both_poses(const TargetFrameSums& sums, const Eigen::Isometry3d& T_target_source);

// Makes the sums blind to translation along their weakest direction when it is held by less than
// min_conditioning of the best one (translation_conditioning, registration.hpp). Where two clouds of
// a tunnel or a corridor slide along each other, what the cost tells along it is noise (where the
// clouds end, range and beam errors), and a graph of such costs moved its submaps by metres
// (docs/pipeline.md, "Blind along a tunnel"). Returns whether it did.
bool drop_weak_translation(TargetFrameSums& sums, double min_conditioning);

}  // namespace gcmap
