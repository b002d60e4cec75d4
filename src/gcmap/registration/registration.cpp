#include "gcmap/registration/registration.hpp"

#include <Eigen/Eigenvalues>

#include "gcmap/core/error.hpp"
#include "gcmap/registration/align.hpp"
#include "gcmap/registration/vgicp.hpp"

namespace gcmap {
namespace {

struct VgicpProblem {
  const PointCloud& source;
  const GaussianVoxelMap& target;
  std::vector<int> associations;  // of the last linearization
  VgicpLinearization linearize(const Eigen::Isometry3d& T) { return linearize_vgicp(source, target, T, associations); }
  VgicpError evaluate(const Eigen::Isometry3d& T) const { return evaluate_vgicp(source, target, T, associations); }
};

struct GicpProblem {
  const PointCloud& source;
  const GicpTarget& target;
  double max_distance;
  std::vector<int> correspondences;
  VgicpLinearization linearize(const Eigen::Isometry3d& T) {
    correspondences = find_correspondences(source, target, T, max_distance);
    return linearize_gicp(source, target, T, correspondences);
  }
  VgicpError evaluate(const Eigen::Isometry3d& T) const { return evaluate_gicp(source, target, T, correspondences); }
};

}  // namespace

RegistrationResult align_vgicp(const PointCloud& source, const GaussianVoxelMap& target, const Eigen::Isometry3d& init,
                               const RegistrationConfig& config) {
  VgicpProblem problem{source, target, {}};
  return align(problem, init, config);
}

RegistrationResult align_gicp(const PointCloud& source, const GicpTarget& target, const Eigen::Isometry3d& init,
                              const RegistrationConfig& config) {
  if (source.covs.size() != source.size()) throw Error("align_gicp: the source cloud has no covariances");
  if (!(config.max_correspondence_distance > 0.0)) throw Error("align_gicp: max_correspondence_distance must be positive");
  GicpProblem problem{source, target, config.max_correspondence_distance, {}};
  return align(problem, init, config);
}

Eigen::Matrix3d translation_information(const Matrix6d& H) {
  const Eigen::Matrix3d Hrr = H.topLeftCorner<3, 3>(), Hrt = H.topRightCorner<3, 3>();
  const Eigen::Matrix3d Htt = H.bottomRightCorner<3, 3>() - Hrt.transpose() * Hrr.ldlt().solve(Hrt);
  return 0.5 * (Htt + Htt.transpose());
}

double translation_conditioning(const Matrix6d& H) {
  const Eigen::Vector3d e =
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(translation_information(H)).eigenvalues().cwiseMax(0.0);
  return e[2] > 0.0 ? e[0] / e[2] : 0.0;
}

}  // namespace gcmap
