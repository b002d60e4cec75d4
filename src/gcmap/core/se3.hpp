#pragma once
// SE(3) on Eigen::Isometry3d. Tangent vectors are [omega; rho] (rotation first), perturbations are
// on the right: T <- T * exp(delta). Every module uses this convention.
#include <Eigen/Core>
#include <Eigen/Geometry>

namespace gcmap {

using Vector6d = Eigen::Matrix<double, 6, 1>;
using Matrix6d = Eigen::Matrix<double, 6, 6>;

Eigen::Matrix3d skew(const Eigen::Vector3d& v);
inline Eigen::Matrix3f skew(const Eigen::Vector3f& v) {
  Eigen::Matrix3f m;
  m << 0.f, -v.z(), v.y(), v.z(), 0.f, -v.x(), -v.y(), v.x(), 0.f;
  return m;
}

Eigen::Matrix3d so3_exp(const Eigen::Vector3d& omega);
Eigen::Vector3d so3_log(const Eigen::Matrix3d& R);
// Left Jacobian of SO(3) and its inverse; the right Jacobian is J_l(-omega).
Eigen::Matrix3d so3_left_jacobian(const Eigen::Vector3d& omega);
Eigen::Matrix3d so3_left_jacobian_inverse(const Eigen::Vector3d& omega);

Eigen::Isometry3d se3_exp(const Vector6d& xi);
Vector6d se3_log(const Eigen::Isometry3d& T);

// Ad_T with T exp(xi) T^-1 = exp(Ad_T xi): [[R, 0], [t^ R, R]].
Matrix6d adjoint(const Eigen::Isometry3d& T);

// J_r^-1(xi): log(exp(xi) exp(d)) ~= xi + J_r^-1(xi) d for small d.
Matrix6d se3_right_jacobian_inverse(const Vector6d& xi);

// Re-orthonormalizes the rotation (accumulated products drift slowly).
Eigen::Isometry3d normalized(const Eigen::Isometry3d& T);

// Pose from translation and unit quaternion (x y z, qx qy qz qw) and back.
Eigen::Isometry3d pose_from_xyz_quat(const double* v7);
void pose_to_xyz_quat(const Eigen::Isometry3d& T, double* v7);

inline double rotation_angle(const Eigen::Isometry3d& T) { return so3_log(T.linear()).norm(); }

}  // namespace gcmap
