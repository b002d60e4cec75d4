#pragma once
// The Levenberg-Marquardt loop of every registration (registration.hpp), over a Problem that
// associates and linearizes: the CPU's VGICP and GICP and the GPU backend's device VGICP share it.
#include <Eigen/Cholesky>

#include "gcmap/registration/registration.hpp"
#include "gcmap/registration/vgicp.hpp"

namespace gcmap {

// Problem: linearize(T) associates at T and returns the blocks; evaluate(T) gives the error under
// the association of the last linearization.
template <class Problem>
RegistrationResult align(Problem& problem, const Eigen::Isometry3d& init, const RegistrationConfig& config) {
  RegistrationResult result;
  result.T_target_source = init;
  double lambda = config.initial_lambda;
  VgicpLinearization lin = problem.linearize(init);

  for (int iter = 0; iter < config.max_iterations; ++iter) {
    result.iterations = iter + 1;
    if (lin.num_inliers == 0) break;
    bool accepted = false;
    Vector6d delta = Vector6d::Zero();
    while (lambda <= config.max_lambda) {
      const Matrix6d A = lin.H_ii + lambda * Matrix6d(lin.H_ii.diagonal().asDiagonal()) + 1e-9 * Matrix6d::Identity();
      delta = A.ldlt().solve(-lin.b_i);
      const Eigen::Isometry3d trial = result.T_target_source * se3_exp(delta);
      const VgicpError e = problem.evaluate(trial);
      if (e.num_inliers > 0 && e.error <= lin.error) {
        result.T_target_source = normalized(trial);
        lambda = std::max(lambda * 0.1, 1e-10);
        accepted = true;
        break;
      }
      lambda *= 10.0;
    }
    if (!accepted) {
      // No descent direction left at any damping: we are at a minimum of the re-associated cost.
      result.converged = true;
      break;
    }
    lin = problem.linearize(result.T_target_source);
    if (delta.head<3>().norm() < config.rotation_eps && delta.tail<3>().norm() < config.translation_eps) {
      result.converged = true;
      break;
    }
  }
  result.num_inliers = lin.num_inliers;
  result.error = lin.error;
  result.H = lin.H_ii;
  return result;
}

}  // namespace gcmap
