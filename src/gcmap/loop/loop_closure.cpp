#include "gcmap/loop/loop_closure.hpp"

#include <Eigen/Eigenvalues>
#include <cmath>

#include "gcmap/core/preprocess.hpp"
#include "gcmap/registration/registration.hpp"

namespace gcmap {

LoopVerification verify_loop(const PointCloud& source_full, const PointCloud& target_full, const Eigen::Isometry3d& init,
                             const LoopConfig& config) {
  LoopVerification out;
  out.T_target_source = init;
  const PointCloud source = voxel_downsample(source_full, config.verification_downsample);
  auto target = std::make_shared<const PointCloud>(voxel_downsample(target_full, config.verification_downsample));
  if (source.size() < 100 || target->size() < 100) return out;
  const GicpTarget gicp_target(target);
  // ScanContext gives the yaw only; the places can be metres apart, so start with wide
  // correspondences and tighten.
  RegistrationConfig reg;
  Matrix6d H = Matrix6d::Zero();
  for (const double distance : {4.0, 2.0, 1.0, 2.0 * config.inlier_distance}) {
    reg.max_correspondence_distance = distance;
    const RegistrationResult r = align_gicp(source, gicp_target, out.T_target_source, reg);
    out.T_target_source = r.T_target_source;
    H = r.H;
  }
  out.conditioning = translation_conditioning(H);
  const std::vector<int> corr = find_correspondences(source, gicp_target, out.T_target_source, config.inlier_distance);
  // Point-to-plane distances (target normal = least-variance axis of its plane-like covariance):
  // point spacing after downsampling would dominate a point-to-point RMSE.
  double sum_sq = 0.0;
  size_t inliers = 0;
  const Eigen::Isometry3f T = out.T_target_source.cast<float>();
  for (size_t i = 0; i < source.size(); ++i) {
    if (corr[i] < 0) continue;
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3f> eig(target->covs[corr[i]]);
    const float d = eig.eigenvectors().col(0).dot(target->points[corr[i]] - T * source.points[i]);
    sum_sq += double(d) * d;
    ++inliers;
  }
  out.inlier_fraction = static_cast<double>(inliers) / source.size();
  out.inlier_rmse = inliers ? std::sqrt(sum_sq / inliers) : 0.0;
  out.accepted = out.inlier_fraction >= config.min_inlier_fraction && out.inlier_rmse <= config.max_inlier_rmse &&
                 out.conditioning >= config.min_conditioning;
  return out;
}

std::shared_ptr<RelativePoseFactor> make_loop_factor(int target_key, int source_key, const Eigen::Isometry3d& T_target_source,
                                                     const LoopConfig& config) {
  const double rot_sigma = config.rotation_sigma_deg * M_PI / 180.0;
  Matrix6d information = Matrix6d::Zero();
  information.diagonal() << Eigen::Vector3d::Constant(1.0 / (rot_sigma * rot_sigma)),
      Eigen::Vector3d::Constant(1.0 / (config.translation_sigma * config.translation_sigma));
  return std::make_shared<RelativePoseFactor>(target_key, source_key, T_target_source, information,
                                              RobustKernel::shifted_tukey(config.tukey_width, config.tukey_offset));
}

}  // namespace gcmap
