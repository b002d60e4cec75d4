#include "gcmap/graph/factors.hpp"

#include <atomic>
#include <cmath>

#include "gcmap/registration/vgicp.hpp"

namespace gcmap {

MatchingCostFactor::MatchingCostFactor(int source_key, int target_key, std::shared_ptr<const PointCloud> source,
                                       std::shared_ptr<const GaussianVoxelMap> target, TrialVoxels trial_voxels)
    : source_(std::move(source)), target_(std::move(target)), trial_voxels_(trial_voxels) {
  keys_ = {source_key, target_key};
}

namespace {
std::atomic<long> kept_points{0};
}  // namespace

long kept_associations() { return kept_points.load(); }

MatchingCostFactor::~MatchingCostFactor() { release_trial_state(); }

void MatchingCostFactor::release_trial_state() {
  if (counted_ == 0) return;
  kept_points -= counted_;
  counted_ = 0;
  std::vector<int>().swap(associations_);
}

void MatchingCostFactor::linearize(const Eigen::Isometry3d* const* poses, FactorLinearization& out) {
  T_lin_ = poses[1]->inverse() * *poses[0];
  if (trial_voxels_ == TrialVoxels::kept_per_optimization && counted_ == 0) {
    const long n = static_cast<long>(source_->size());
    if (kept_points.fetch_add(n) + n <= kMaxKeptAssociations) counted_ = n;
    else kept_points -= n;
  }
  const bool keep = trial_voxels_ == TrialVoxels::kept || counted_ > 0;
  to_factor_linearization(conditioned(keep ? linearize_vgicp(*source_, *target_, T_lin_, associations_, robust_width_)
                                           : linearize_vgicp(*source_, *target_, T_lin_, robust_width_),
                                      T_lin_),
                          out);
}

VgicpLinearization MatchingCostFactor::conditioned(const VgicpLinearization& lin,
                                                   const Eigen::Isometry3d& T_target_source) const {
  if (!(min_conditioning_ > 0.0)) return lin;
  TargetFrameSums sums{lin.H_jj, lin.b_j, lin.error, lin.num_inliers};
  return drop_weak_translation(sums, min_conditioning_) ? expand_to_both_poses(sums, T_target_source) : lin;
}

void to_factor_linearization(const VgicpLinearization& lin, FactorLinearization& out) {
  out.H.topLeftCorner<6, 6>() = lin.H_ii;
  out.H.topRightCorner<6, 6>() = lin.H_ij;
  out.H.bottomLeftCorner<6, 6>() = lin.H_ij.transpose();
  out.H.bottomRightCorner<6, 6>() = lin.H_jj;
  out.b << lin.b_i, lin.b_j;
  out.error = lin.error;
}

double MatchingCostFactor::trial_error(const Eigen::Isometry3d* const* poses) const {
  const Eigen::Isometry3d T = poses[1]->inverse() * *poses[0];
  if (associations_.size() == source_->size()) return evaluate_vgicp(*source_, *target_, T, associations_, robust_width_).error;
  return evaluate_vgicp(*source_, *target_, T, T_lin_, robust_width_).error;
}

RelativePoseFactor::RelativePoseFactor(int key_i, int key_j, const Eigen::Isometry3d& measured, const Matrix6d& information,
                                       RobustKernel kernel)
    : measured_(measured), information_(information), kernel_(kernel) {
  keys_ = {key_i, key_j};
}

Vector6d RelativePoseFactor::residual(const Eigen::Isometry3d& T_i, const Eigen::Isometry3d& T_j) const {
  return se3_log(measured_.inverse() * T_i.inverse() * T_j);
}

void RelativePoseFactor::linearize(const Eigen::Isometry3d* const* poses, FactorLinearization& out) {
  const Eigen::Isometry3d& T_i = *poses[0];
  const Eigen::Isometry3d& T_j = *poses[1];
  const Vector6d e = residual(T_i, T_j);
  weight_ = kernel_.weight(std::sqrt(std::max(0.0, e.dot(information_ * e))));
  const Matrix6d Jr_inv = se3_right_jacobian_inverse(e);
  Eigen::Matrix<double, 6, 12> J;
  J.leftCols<6>() = -Jr_inv * adjoint(T_j.inverse() * T_i);
  J.rightCols<6>() = Jr_inv;
  const Eigen::Matrix<double, 12, 6> JtW = weight_ * J.transpose() * information_;
  out.H = JtW * J;
  out.b = JtW * e;
  out.error = weight_ * e.dot(information_ * e);
}

double RelativePoseFactor::trial_error(const Eigen::Isometry3d* const* poses) const {
  const Vector6d e = residual(*poses[0], *poses[1]);
  return weight_ * e.dot(information_ * e);
}

std::shared_ptr<RelativePoseFactor> gyro_rotation_factor(int key_i, int key_j, const GyroRotation& gyro) {
  Eigen::Isometry3d measured = Eigen::Isometry3d::Identity();
  measured.linear() = gyro.R;
  Matrix6d information = Matrix6d::Zero();  // [rotation; translation]
  information.topLeftCorner<3, 3>() = Eigen::Matrix3d::Identity() / gyro.variance;
  return std::make_shared<RelativePoseFactor>(key_i, key_j, measured, information);
}

std::shared_ptr<RelativePoseFactor> gyro_motion_factor(int key_i, int key_j, const GyroRotation& gyro,
                                                       const Eigen::Vector3d& t_i_j, double translation_sigma) {
  Eigen::Isometry3d measured = Eigen::Isometry3d::Identity();
  measured.linear() = gyro.R;
  measured.translation() = t_i_j;
  Matrix6d information = Matrix6d::Zero();  // [rotation; translation]
  information.topLeftCorner<3, 3>() = Eigen::Matrix3d::Identity() / gyro.variance;
  information.bottomRightCorner<3, 3>() = Eigen::Matrix3d::Identity() / (translation_sigma * translation_sigma);
  return std::make_shared<RelativePoseFactor>(key_i, key_j, measured, information);
}

}  // namespace gcmap
