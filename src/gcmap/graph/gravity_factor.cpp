#include "gcmap/graph/gravity_factor.hpp"

#include <algorithm>
#include <cmath>

#include "gcmap/core/error.hpp"
#include "gcmap/graph/imu_preintegration.hpp"

namespace gcmap {

namespace {
// Fills a linearization over `cols` columns from a residual, its Jacobian and one information scale.
template <int N, int C>
void fill(const Eigen::Matrix<double, N, 1>& e, const Eigen::Matrix<double, N, C>& J, double information,
          FactorLinearization& out) {
  out.H.setZero();
  out.b.setZero();
  out.H.topLeftCorner<C, C>() = information * J.transpose() * J;
  out.b.head<C>() = information * J.transpose() * e;
  out.error = information * e.squaredNorm();
}
}  // namespace

GravityFactor::GravityFactor(const GravityWindow& window, int bias_key, double gravity, RobustKernel kernel)
    : window_(window), gravity_(gravity), kernel_(kernel) {
  if (!(window.sigma > 0.0) || !(window.duration > 0.0)) throw Error("GravityFactor: sigma and duration must be > 0");
  information_ = 1.0 / std::pow(window.sigma * gravity, 2);
  keys_ = {window.submap, bias_key};
}

Eigen::Vector3d GravityFactor::residual(const Eigen::Isometry3d& T, const Eigen::Isometry3d& bias) const {
  return T.linear() * window_.gravity(bias.translation()) - gravity_vector(gravity_);
}

Eigen::Matrix<double, 3, 12> GravityFactor::jacobian(const Eigen::Isometry3d& T, const Eigen::Isometry3d& bias) const {
  Eigen::Matrix<double, 3, 12> J = Eigen::Matrix<double, 3, 12>::Zero();
  J.leftCols<3>() = -T.linear() * skew(window_.gravity(bias.translation()));
  J.rightCols<3>() = -T.linear() * window_.M * bias.linear() / window_.duration;
  return J;
}

double GravityFactor::tilt(const Eigen::Isometry3d& T, const Eigen::Isometry3d& bias) const {
  const Eigen::Vector3d up = T.linear() * window_.up(bias.translation());
  return std::acos(std::clamp(up.z(), -1.0, 1.0));
}

void GravityFactor::linearize(const Eigen::Isometry3d* const* poses, FactorLinearization& out) {
  const Eigen::Vector3d e = residual(*poses[0], *poses[1]);
  weight_ = kernel_.weight(std::sqrt(information_) * e.norm());
  fill<3, 12>(e, jacobian(*poses[0], *poses[1]), weight_ * information_, out);
}

double GravityFactor::trial_error(const Eigen::Isometry3d* const* poses) const {
  return weight_ * information_ * residual(*poses[0], *poses[1]).squaredNorm();
}

AccelBiasPriorFactor::AccelBiasPriorFactor(int key, double sigma) {
  if (!(sigma > 0.0)) throw Error("AccelBiasPriorFactor: sigma must be > 0");
  information_ = 1.0 / (sigma * sigma);
  keys_ = {key, -1};
}

// The rotation is held a million times stiffer than the bias, so it never leaves the identity,
// where the rotation vector's Jacobian is the identity.
void AccelBiasPriorFactor::linearize(const Eigen::Isometry3d* const* poses, FactorLinearization& out) {
  const Eigen::Isometry3d& T = *poses[0];
  Vector6d e;
  e << 1e3 * so3_log(T.linear()), T.translation();
  Eigen::Matrix<double, 6, 6> J = Eigen::Matrix<double, 6, 6>::Zero();
  J.topLeftCorner<3, 3>() = 1e3 * Eigen::Matrix3d::Identity();
  J.bottomRightCorner<3, 3>() = T.linear();
  fill<6, 6>(e, J, information_, out);
}

double AccelBiasPriorFactor::trial_error(const Eigen::Isometry3d* const* poses) const {
  return information_ * (1e6 * so3_log(poses[0]->linear()).squaredNorm() + poses[0]->translation().squaredNorm());
}

HeadingPositionFactor::HeadingPositionFactor(int key, const Eigen::Isometry3d& held, double sigma) : p0_(held.translation()) {
  if (!(sigma > 0.0)) throw Error("HeadingPositionFactor: sigma must be > 0");
  Eigen::Vector3d h0 = held.linear().col(0);
  h0.z() = 0.0;
  if (!(h0.norm() > 1e-3)) throw Error("HeadingPositionFactor: the held pose's x axis is vertical");
  normal_ = Eigen::Vector3d::UnitZ().cross(h0.normalized());
  information_ = 1.0 / (sigma * sigma);
  keys_ = {key, -1};
}

Eigen::Vector4d HeadingPositionFactor::residual(const Eigen::Isometry3d& T) const {
  Eigen::Vector4d e;
  e << normal_.dot(T.linear().col(0)), T.translation() - p0_;
  return e;
}

Eigen::Matrix<double, 4, 6> HeadingPositionFactor::jacobian(const Eigen::Isometry3d& T) const {
  Eigen::Matrix<double, 4, 6> J = Eigen::Matrix<double, 4, 6>::Zero();
  J.block<1, 3>(0, 0) = -normal_.transpose() * T.linear() * skew(Eigen::Vector3d(Eigen::Vector3d::UnitX()));
  J.block<3, 3>(1, 3) = T.linear();
  return J;
}

void HeadingPositionFactor::linearize(const Eigen::Isometry3d* const* poses, FactorLinearization& out) {
  fill<4, 6>(residual(*poses[0]), jacobian(*poses[0]), information_, out);
}

double HeadingPositionFactor::trial_error(const Eigen::Isometry3d* const* poses) const {
  return information_ * residual(*poses[0]).squaredNorm();
}

}  // namespace gcmap
