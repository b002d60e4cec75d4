#pragma once
// Factors over NavStates (pose, velocity, IMU biases: graph/imu_preintegration.hpp), each a
// residual with its Jacobians over the 15-dimensional tangents of the states it touches, whitened
// so that its error is |r|^2. The pose-only LevenbergMarquardt does not take them yet: a dense LM
// over a few states (optimize_nav_states) solves them on their own.
#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <memory>
#include <vector>

#include "gcmap/graph/imu_preintegration.hpp"

namespace gcmap {

using Matrix15d = Eigen::Matrix<double, 15, 15>;

struct NavLinearization {
  Eigen::VectorXd r;                 // whitened residual
  std::array<Eigen::MatrixXd, 2> J;  // whitened dr/d(tangent) of keys()[0], keys()[1]
};

class NavFactor {
 public:
  virtual ~NavFactor() = default;
  virtual int num_keys() const = 0;
  const std::array<int, 2>& keys() const { return keys_; }
  // states[k] is the state of keys()[k].
  virtual NavLinearization linearize(const NavState* const* states) const = 0;
  double error(const NavState* const* states) const { return linearize(states).r.squaredNorm(); }

 protected:
  std::array<int, 2> keys_{-1, -1};
};

// Preintegrated IMU between states i and j (Forster Eq. 45): r = [r_dR, r_dv, r_dp] at the bias of
// state i, corrected to first order, whitened by the preintegration's covariance. The bias of j is
// left to a BiasRandomWalkFactor.
class ImuFactor : public NavFactor {
 public:
  ImuFactor(int key_i, int key_j, ImuPreintegration preintegration, const Eigen::Vector3d& gravity = gravity_vector());
  int num_keys() const override { return 2; }
  NavLinearization linearize(const NavState* const* states) const override;
  // The unwhitened residual and its Jacobians over state i's and j's tangents.
  Vector9d residual(const NavState& i, const NavState& j, Eigen::Matrix<double, 9, 15>* J_i = nullptr,
                    Eigen::Matrix<double, 9, 15>* J_j = nullptr) const;
  const ImuPreintegration& preintegration() const { return pre_; }
  // Gravity as an unknown (odometry/inertial_track.hpp estimates its direction): the whitened
  // residual's derivative by the gravity vector, which enters linearly.
  Eigen::Matrix<double, 9, 3> gravity_jacobian(const NavState& i) const;
  void set_gravity(const Eigen::Vector3d& gravity) { gravity_ = gravity; }

 private:
  ImuPreintegration pre_;
  Eigen::Vector3d gravity_;
  Matrix9d sqrt_information_;
};

// The biases of i and j differ by a random walk over dt seconds: r = b_j - b_i with covariance
// (bias walk density)^2 dt.
class BiasRandomWalkFactor : public NavFactor {
 public:
  BiasRandomWalkFactor(int key_i, int key_j, double dt, const ImuNoise& noise);
  int num_keys() const override { return 2; }
  NavLinearization linearize(const NavState* const* states) const override;

 private:
  Vector6d sqrt_information_;
};

// A state is near `prior`: r = [log(T_prior^-1 T); v - v_prior; b - b_prior], whitened by the
// square root of a 15x15 information matrix.
class NavPriorFactor : public NavFactor {
 public:
  NavPriorFactor(int key, const NavState& prior, const Matrix15d& information);
  int num_keys() const override { return 1; }
  NavLinearization linearize(const NavState* const* states) const override;

 private:
  NavState prior_;
  Matrix15d sqrt_information_;
};

// How far T lies from T_measured: [log(R_measured^T R), R_measured^T (t - t_measured)], the
// translation apart from the rotation. The SE(3) log would mix them (its translation is V^-1 of
// this one), so a slide along a direction the measurement leaves free (a tunnel's axis) would
// reappear, turned by half the rotation's error, in the directions it constrains.
Vector6d pose_difference(const Eigen::Isometry3d& T_measured, const Eigen::Isometry3d& T);

// A LiDAR pose measured (a registration): r = pose_difference(T_measured, T_world_imu T_imu_lidar),
// [rotation, translation], whitened by the square root of its 6x6 information, which may be singular
// (a translation the scan cannot see): such a direction costs nothing.
class LidarPoseFactor : public NavFactor {
 public:
  LidarPoseFactor(int key, const Eigen::Isometry3d& T_world_lidar, const Matrix6d& information,
                  const Eigen::Isometry3d& T_imu_lidar);
  int num_keys() const override { return 1; }
  NavLinearization linearize(const NavState* const* states) const override;

 private:
  Eigen::Isometry3d T_world_lidar_, T_imu_lidar_;
  Matrix6d sqrt_information_;
};

struct NavOptimizationResult {
  int iterations = 0;
  double initial_error = 0.0, final_error = 0.0;
  bool converged = false;
};

// The damped Gauss-Newton loop of optimize_nav_states over any unknowns: system(H, b) linearizes at
// the current values, trial(d) returns the error of the values moved by d and keeps them, accept()
// makes the kept ones current. error: the current values' error.
template <class System, class Trial, class Accept>
NavOptimizationResult dense_levenberg_marquardt(double error, int max_iterations, System&& system, Trial&& trial,
                                                Accept&& accept) {
  NavOptimizationResult result;
  result.initial_error = error;
  double lambda = 1e-6;
  Eigen::MatrixXd H;
  Eigen::VectorXd b;
  for (; result.iterations < max_iterations && !result.converged; ++result.iterations) {
    system(H, b);
    bool accepted = false;
    for (; lambda < 1e10 && !accepted; lambda *= 10.0) {
      Eigen::MatrixXd A = H;
      A.diagonal() += lambda * H.diagonal().cwiseMax(1e-9);
      const Eigen::VectorXd d = A.ldlt().solve(-b);
      const double e = trial(d);
      if (!(e < error)) continue;
      result.converged = error - e < 1e-10 * std::max(error, 1e-12) || d.lpNorm<Eigen::Infinity>() < 1e-10;
      accept();
      error = e, accepted = true;
      lambda = std::max(lambda / 100.0, 1e-12);
    }
    if (!accepted) result.converged = true;  // no step lowers the error: at a minimum
  }
  result.final_error = error;
  return result;
}

// Dense Levenberg-Marquardt over states[0..n): for a handful of states (tests, initialization).
// Throws Error when a factor references a missing state.
NavOptimizationResult optimize_nav_states(const std::vector<std::unique_ptr<NavFactor>>& factors, std::vector<NavState>& states,
                                          int max_iterations = 50);
// The Gauss-Newton system H d = -b (H = J^T J, b = J^T r) of all states at their values, 15 rows per state.
void nav_system(const std::vector<std::unique_ptr<NavFactor>>& factors, const std::vector<NavState>& states, Eigen::MatrixXd& H,
                Eigen::VectorXd& b);
// The sum of the factors' squared whitened residuals.
double nav_error(const std::vector<std::unique_ptr<NavFactor>>& factors, const std::vector<NavState>& states);
// The Gauss-Newton information (J^T J) of all states at their values, 15 rows per state.
Eigen::MatrixXd nav_information(const std::vector<std::unique_ptr<NavFactor>>& factors, const std::vector<NavState>& states);

}  // namespace gcmap
