#include "gcmap/graph/gnss_factor.hpp"

#include <cmath>

#include "gcmap/core/error.hpp"

namespace gcmap {

GnssPositionFactor::GnssPositionFactor(int key, const Eigen::Vector3d& p_pose_antenna, const Eigen::Vector3d& measured,
                                       const Eigen::Vector3d& sigma, RobustKernel kernel)
    : p_(p_pose_antenna), measured_(measured), kernel_(kernel) {
  if (!(sigma.minCoeff() > 0.0)) throw Error("GnssPositionFactor: sigmas must be > 0");
  information_ = sigma.cwiseProduct(sigma).cwiseInverse();
  keys_ = {key, -1};
}

double GnssPositionFactor::whitened_norm(const Eigen::Isometry3d& T) const {
  const Eigen::Vector3d e = residual(T);
  return std::sqrt(e.dot(information_.cwiseProduct(e)));
}

Eigen::Matrix<double, 3, 6> GnssPositionFactor::jacobian(const Eigen::Isometry3d& T) const {
  Eigen::Matrix<double, 3, 6> J;
  J.leftCols<3>() = -T.linear() * skew(p_);
  J.rightCols<3>() = T.linear();
  return J;
}

void GnssPositionFactor::linearize(const Eigen::Isometry3d* const* poses, FactorLinearization& out) {
  const Eigen::Isometry3d& T = *poses[0];
  const Eigen::Vector3d e = residual(T);
  weight_ = kernel_.weight(whitened_norm(T));
  const Eigen::Matrix<double, 3, 6> J = jacobian(T);
  const Eigen::Matrix<double, 6, 3> JtW = weight_ * J.transpose() * information_.asDiagonal();
  out.H.setZero();
  out.b.setZero();
  out.H.topLeftCorner<6, 6>() = JtW * J;
  out.b.head<6>() = JtW * e;
  out.error = weight_ * e.dot(information_.cwiseProduct(e));
}

double GnssPositionFactor::trial_error(const Eigen::Isometry3d* const* poses) const {
  const Eigen::Vector3d e = residual(*poses[0]);
  return weight_ * e.dot(information_.cwiseProduct(e));
}

}  // namespace gcmap
