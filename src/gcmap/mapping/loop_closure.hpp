#pragma once
// Verification of a loop candidate and the constraint it becomes (paper Section III-C).
#include "gcmap/graph/factors.hpp"
#include "gcmap/mapping/config.hpp"

namespace gcmap {

struct LoopVerification {
  bool accepted = false;
  Eigen::Isometry3d T_target_source = Eigen::Isometry3d::Identity();
  double inlier_fraction = 0.0;  // source points with a target point within inlier_distance
  double inlier_rmse = 0.0;      // m, point-to-plane, over those points
};

// GICP (kNN) from `init`, coarse to fine, on both clouds downsampled; accepted only on a high
// inlier fraction and a low inlier RMSE. Both clouds need covariances.
LoopVerification verify_loop(const PointCloud& source, const PointCloud& target, const Eigen::Isometry3d& init,
                             const LoopConfig& config);

// The constraint T_target^-1 T_source ~ measured with constant information and the shifted Tukey
// kernel: it pulls while the estimate is far from the loop, lets go once it is satisfied, and
// ignores grossly wrong loops.
std::shared_ptr<RelativePoseFactor> make_loop_factor(int target_key, int source_key,
                                                     const Eigen::Isometry3d& T_target_source, const LoopConfig& config);

}  // namespace gcmap
