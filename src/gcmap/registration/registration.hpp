#pragma once
#include "gcmap/core/gaussian_voxel_map.hpp"
#include "gcmap/core/point_cloud.hpp"
#include "gcmap/core/se3.hpp"
#include "gcmap/registration/gicp.hpp"

namespace gcmap {

struct RegistrationConfig {
  int max_iterations = 64;
  // Converged when an accepted step rotates less than this (rad) and translates less than this (m).
  double rotation_eps = 1e-4;
  double translation_eps = 1e-4;
  double initial_lambda = 1e-6;
  double max_lambda = 1e8;
  double max_correspondence_distance = 1.0;  // GICP only (m)
};

struct RegistrationResult {
  Eigen::Isometry3d T_target_source = Eigen::Isometry3d::Identity();
  bool converged = false;
  int iterations = 0;
  size_t num_inliers = 0;
  double error = 0.0;
  Matrix6d H = Matrix6d::Zero();  // Gauss-Newton Hessian at the solution (information of T_target_source)
};

// Levenberg-Marquardt on T_target_source with right perturbations. Each iteration re-associates
// at the current pose; a trial step is accepted only when it lowers the error under that same
// association (re-associating at the trial pose would let newly matched points mask progress).
RegistrationResult align_vgicp(const PointCloud& source, const GaussianVoxelMap& target,
                               const Eigen::Isometry3d& init_T_target_source, const RegistrationConfig& config = {});
RegistrationResult align_gicp(const PointCloud& source, const GicpTarget& target, const Eigen::Isometry3d& init_T_target_source,
                              const RegistrationConfig& config = {});

// The translation block of a registration's Hessian (rotation first) with the rotation marginalized
// (Schur complement): how well the translation is held once the rotation is free.
Eigen::Matrix3d translation_information(const Matrix6d& H);

// Smallest over largest eigenvalue of translation_information(H): 1 held alike in every direction,
// near 0 degenerate (parallel structure: a tunnel, a straight road's rails).
double translation_conditioning(const Matrix6d& H);

}  // namespace gcmap
