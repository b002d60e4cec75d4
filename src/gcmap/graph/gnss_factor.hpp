#pragma once
// A GNSS fix on one pose: the antenna, a fixed point of that pose's frame (the fix's stamp
// interpolated between the frames around it, lever arm included), must be where the fix says, in
// the frame the poses live in (local ENU once georeferenced). error = e^T W e with
// e = T p - z and W = diag(1/sigma^2) per axis, under an IRLS robust kernel whose weight is
// refreshed at each linearization (multipath outliers). Jacobian for T <- T exp([omega; rho]):
// de/d omega = -R [p]x, de/d rho = R.
#include "gcmap/graph/factors.hpp"

namespace gcmap {

class GnssPositionFactor : public Factor {
 public:
  GnssPositionFactor(int key, const Eigen::Vector3d& p_pose_antenna, const Eigen::Vector3d& measured,
                     const Eigen::Vector3d& sigma, RobustKernel kernel = {});
  int num_keys() const override { return 1; }
  void linearize(const Eigen::Isometry3d* const* poses, FactorLinearization& out) override;
  double trial_error(const Eigen::Isometry3d* const* poses) const override;

  Eigen::Vector3d residual(const Eigen::Isometry3d& T) const { return T * p_ - measured_; }
  // sqrt(e^T W e): the residual in sigmas.
  double whitened_norm(const Eigen::Isometry3d& T) const;
  Eigen::Matrix<double, 3, 6> jacobian(const Eigen::Isometry3d& T) const;
  double weight() const { return weight_; }
  const Eigen::Vector3d& measured() const { return measured_; }
  const Eigen::Vector3d& antenna() const { return p_; }

 private:
  Eigen::Vector3d p_, measured_, information_;  // information: 1/sigma^2 per axis
  RobustKernel kernel_;
  double weight_ = 1.0;
};

}  // namespace gcmap
