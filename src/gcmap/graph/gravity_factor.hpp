#pragma once
// Factors that tie a pose graph to gravity. An accelerometer, over a window of known motion,
// measures gravity in a pose's frame up to its own bias (graph/gravity_window.hpp); the world's gravity
// is along -z. The bias is a variable of the graph, carried by a pose whose translation is the
// bias and whose rotation stays the identity (AccelBiasPriorFactor), so the pose-only LM solves
// it jointly with the poses: a bias fixed to the body turns with it, gravity does not.
// They fix roll and pitch only, so a graph whose first pose is no longer held needs its position
// and heading held otherwise (HeadingPositionFactor). Jacobians are for T <- T exp([omega; rho]).
#include "gcmap/graph/factors.hpp"

namespace gcmap {

// One window's gravity in a pose's frame: g T = c - M b_a for the accelerometer bias b_a (IMU frame).
struct GravityWindow {
  int submap = 0;
  Eigen::Vector3d c = Eigen::Vector3d::Zero();  // m/s
  Eigen::Matrix3d M = Eigen::Matrix3d::Zero();  // s
  double duration = 0.0;                        // s (T)
  double sigma = 0.0;                           // rad: of the up direction

  Eigen::Vector3d gravity(const Eigen::Vector3d& accel_bias) const { return (c - M * accel_bias) / duration; }
  Eigen::Vector3d up(const Eigen::Vector3d& accel_bias) const { return -gravity(accel_bias).normalized(); }
};

// Keys: the window's pose, the bias pose. e = R g(b) - (0, 0, -g_world) (m/s^2), whitened by
// sigma * g_world per component, under an IRLS Huber weight refreshed at each linearization.
// de/d omega = -R [g(b)]x; de/d rho_bias = -R M R_bias / T.
class GravityFactor : public Factor {
 public:
  GravityFactor(const GravityWindow& window, int bias_key, double gravity, RobustKernel kernel = {});
  int num_keys() const override { return 2; }
  void linearize(const Eigen::Isometry3d* const* poses, FactorLinearization& out) override;
  double trial_error(const Eigen::Isometry3d* const* poses) const override;

  Eigen::Vector3d residual(const Eigen::Isometry3d& T, const Eigen::Isometry3d& bias) const;
  // Over [pose, bias], 3 x 12.
  Eigen::Matrix<double, 3, 12> jacobian(const Eigen::Isometry3d& T, const Eigen::Isometry3d& bias) const;
  // The angle (rad) between the measured up, turned into the world, and the world's z.
  double tilt(const Eigen::Isometry3d& T, const Eigen::Isometry3d& bias) const;
  double weight() const { return weight_; }

 private:
  GravityWindow window_;
  double gravity_, information_;
  RobustKernel kernel_;
  double weight_ = 1.0;
};

// The bias pose: its translation (the bias) near zero with `sigma`, its rotation held at the identity.
class AccelBiasPriorFactor : public Factor {
 public:
  AccelBiasPriorFactor(int key, double sigma);
  int num_keys() const override { return 1; }
  void linearize(const Eigen::Isometry3d* const* poses, FactorLinearization& out) override;
  double trial_error(const Eigen::Isometry3d* const* poses) const override;

 private:
  double information_;
};

// Holds a pose's position and heading where they were, and leaves its roll and pitch free:
// e = [(z x h0) . R x; p - p0] with h0 the horizontal unit heading of the held pose's x axis, each
// component over `sigma`. The heading term is the sine of the heading change (near level).
class HeadingPositionFactor : public Factor {
 public:
  HeadingPositionFactor(int key, const Eigen::Isometry3d& held, double sigma);
  int num_keys() const override { return 1; }
  void linearize(const Eigen::Isometry3d* const* poses, FactorLinearization& out) override;
  double trial_error(const Eigen::Isometry3d* const* poses) const override;

  Eigen::Vector4d residual(const Eigen::Isometry3d& T) const;
  Eigen::Matrix<double, 4, 6> jacobian(const Eigen::Isometry3d& T) const;

 private:
  Eigen::Vector3d normal_, p0_;  // normal_ = z x h0
  double information_;
};

}  // namespace gcmap
