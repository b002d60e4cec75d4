#include "gcmap/core/se3.hpp"

#include <cmath>

namespace gcmap {

Eigen::Matrix3d skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0.0, -v.z(), v.y(), v.z(), 0.0, -v.x(), -v.y(), v.x(), 0.0;
  return m;
}

Eigen::Matrix3d so3_exp(const Eigen::Vector3d& omega) {
  const double theta2 = omega.squaredNorm();
  const Eigen::Matrix3d W = skew(omega);
  if (theta2 < 1e-12) return Eigen::Matrix3d::Identity() + W + 0.5 * W * W;
  const double theta = std::sqrt(theta2);
  return Eigen::Matrix3d::Identity() + (std::sin(theta) / theta) * W + ((1.0 - std::cos(theta)) / theta2) * W * W;
}

Eigen::Vector3d so3_log(const Eigen::Matrix3d& R) {
  // The quaternion route is stable near 0 and near pi.
  Eigen::Quaterniond q(R);
  q.normalize();
  if (q.w() < 0) q.coeffs() *= -1.0;
  const Eigen::Vector3d v = q.vec();
  const double s = v.norm();
  if (s < 1e-10) return 2.0 * v / q.w();
  const double theta = 2.0 * std::atan2(s, q.w());
  return v * (theta / s);
}

Eigen::Matrix3d so3_left_jacobian(const Eigen::Vector3d& omega) {
  const double theta2 = omega.squaredNorm();
  const Eigen::Matrix3d W = skew(omega);
  if (theta2 < 1e-10) return Eigen::Matrix3d::Identity() + 0.5 * W + W * W / 6.0;
  const double theta = std::sqrt(theta2);
  return Eigen::Matrix3d::Identity() + ((1.0 - std::cos(theta)) / theta2) * W +
         ((theta - std::sin(theta)) / (theta2 * theta)) * W * W;
}

Eigen::Matrix3d so3_left_jacobian_inverse(const Eigen::Vector3d& omega) {
  const double theta2 = omega.squaredNorm();
  const Eigen::Matrix3d W = skew(omega);
  if (theta2 < 1e-10) return Eigen::Matrix3d::Identity() - 0.5 * W + W * W / 12.0;
  const double theta = std::sqrt(theta2);
  const double half = 0.5 * theta;
  const double coef = (1.0 - half * std::cos(half) / std::sin(half)) / theta2;
  return Eigen::Matrix3d::Identity() - 0.5 * W + coef * W * W;
}

Eigen::Isometry3d se3_exp(const Vector6d& xi) {
  const Eigen::Vector3d omega = xi.head<3>();
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = so3_exp(omega);
  T.translation() = so3_left_jacobian(omega) * xi.tail<3>();
  return T;
}

Vector6d se3_log(const Eigen::Isometry3d& T) {
  Vector6d xi;
  xi.head<3>() = so3_log(T.linear());
  xi.tail<3>() = so3_left_jacobian_inverse(xi.head<3>()) * T.translation();
  return xi;
}

Matrix6d adjoint(const Eigen::Isometry3d& T) {
  Matrix6d A = Matrix6d::Zero();
  const Eigen::Matrix3d R = T.linear();
  A.block<3, 3>(0, 0) = R;
  A.block<3, 3>(3, 3) = R;
  A.block<3, 3>(3, 0) = skew(Eigen::Vector3d(T.translation())) * R;
  return A;
}

namespace {
// Q(omega, rho) of the SE(3) left Jacobian [[J, 0], [Q, J]] (Barfoot, State Estimation, eq. 7.86).
Eigen::Matrix3d se3_q(const Eigen::Vector3d& omega, const Eigen::Vector3d& rho) {
  const Eigen::Matrix3d W = skew(omega);
  const Eigen::Matrix3d P = skew(rho);
  const double theta2 = omega.squaredNorm();
  double c1, c2, c3;
  if (theta2 < 1e-8) {
    c1 = 1.0 / 6.0;
    c2 = 1.0 / 24.0;
    c3 = 1.0 / 120.0;
  } else {
    const double theta = std::sqrt(theta2);
    const double s = std::sin(theta), c = std::cos(theta);
    c1 = (theta - s) / (theta2 * theta);
    c2 = (theta2 + 2.0 * c - 2.0) / (2.0 * theta2 * theta2);
    c3 = (2.0 * theta - 3.0 * s + theta * c) / (2.0 * theta2 * theta2 * theta);
  }
  const Eigen::Matrix3d WP = W * P, PW = P * W, WPW = W * P * W;
  return 0.5 * P + c1 * (WP + PW + WPW) + c2 * (W * WP + PW * W - 3.0 * WPW) + c3 * (WPW * W + W * WPW);
}
}  // namespace

Matrix6d se3_right_jacobian_inverse(const Vector6d& xi) {
  // J_r(xi) = J_l(-xi).
  const Eigen::Vector3d omega = -xi.head<3>();
  const Eigen::Vector3d rho = -xi.tail<3>();
  const Eigen::Matrix3d Jinv = so3_left_jacobian_inverse(omega);
  Matrix6d out = Matrix6d::Zero();
  out.block<3, 3>(0, 0) = Jinv;
  out.block<3, 3>(3, 3) = Jinv;
  out.block<3, 3>(3, 0) = -Jinv * se3_q(omega, rho) * Jinv;
  return out;
}

Eigen::Isometry3d normalized(const Eigen::Isometry3d& T) {
  Eigen::Isometry3d out = T;
  out.linear() = Eigen::Quaterniond(T.linear()).normalized().toRotationMatrix();
  return out;
}

Eigen::Isometry3d pose_from_xyz_quat(const double* v) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Eigen::Vector3d(v[0], v[1], v[2]);
  T.linear() = Eigen::Quaterniond(v[6], v[3], v[4], v[5]).normalized().toRotationMatrix();
  return T;
}

void pose_to_xyz_quat(const Eigen::Isometry3d& T, double* v) {
  const Eigen::Quaterniond q(T.linear());
  v[0] = T.translation().x();
  v[1] = T.translation().y();
  v[2] = T.translation().z();
  v[3] = q.x();
  v[4] = q.y();
  v[5] = q.z();
  v[6] = q.w();
}

}  // namespace gcmap
