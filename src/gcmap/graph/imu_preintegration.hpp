#pragma once
// IMU preintegration on the manifold (Forster et al., TRO 2017): the rotation, velocity and
// position deltas between two states from the gyro and accelerometer samples between them, their
// 9x9 covariance ([dphi, dv, dp] order) and their first-order dependence on the biases.
// Frames: the world is z up with gravity along -z; samples are in the IMU frame.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <vector>

#include "gcmap/core/imu_sample.hpp"
#include "gcmap/core/se3.hpp"

namespace gcmap {

using Matrix9d = Eigen::Matrix<double, 9, 9>;
using Vector9d = Eigen::Matrix<double, 9, 1>;
using Vector15d = Eigen::Matrix<double, 15, 1>;

// Continuous-time noise densities and bias random walks. Defaults: a MEMS IMU as built into
// LiDARs (Livox, Ouster); datasheet figures inflated for vibration.
struct ImuNoise {
  double gyro_noise = 1.7e-3;       // rad/s/sqrt(Hz)
  double accel_noise = 2.0e-2;      // m/s^2/sqrt(Hz)
  double gyro_bias_walk = 2.0e-5;   // rad/s^2/sqrt(Hz)
  double accel_bias_walk = 3.0e-4;  // m/s^3/sqrt(Hz)
};

// The `imu:` config section (mapping/config.cpp owns the keys): whether an IMU the input carries is
// used, how it sits on the LiDAR, its clock and its noise.
struct ImuConfig {
  bool use = true;
  bool level_map = true;  // the accelerometer's gravity levels the global graph (graph/gravity_window.hpp)
  bool inertial_odometry = true;  // IMU-propagated states predict the sweeps (odometry/inertial_track.hpp)
  bool smooth_rotations = true;   // the trajectory's rotations refined with the gyro (graph/rotation_smoother.hpp)
  // The IMU frame in the LiDAR frame: a translation (m) and roll, pitch, yaw (deg, applied in that
  // order about the LiDAR's fixed axes).
  double x = 0.0, y = 0.0, z = 0.0, roll_deg = 0.0, pitch_deg = 0.0, yaw_deg = 0.0;
  double time_offset = 0.0;  // s: an IMU stamp minus the LiDAR's stamp of the same instant
  // The estimation's accelerometer density is five times the sensor's (ImuNoise): the registration
  // claims centimetres where a sensor in hand jumps by decimetres, and a state whose velocity the
  // accelerometer held tighter stopped listening to the registration; walks diverged
  // (docs/benchmarks.md, "The accelerometer's noise in the state").
  ImuNoise noise{.accel_noise = 0.1};
  double gravity = kStandardGravity;  // m/s^2, along -z of the world

  // A point in the IMU frame to the LiDAR frame.
  Eigen::Isometry3d T_lidar_imu() const;
};

struct ImuBias {
  Eigen::Vector3d gyro = Eigen::Vector3d::Zero();
  Eigen::Vector3d accel = Eigen::Vector3d::Zero();
  Vector6d vector() const { return (Vector6d() << gyro, accel).finished(); }
  static ImuBias from_vector(const Vector6d& b) { return {b.head<3>(), b.tail<3>()}; }
};

// A state of LiDAR-inertial estimation. Its tangent space (15) is [dphi, drho] of the pose (right
// perturbation, as everywhere: T <- T exp(d)), dv (world frame), dbg, dba (additive).
struct NavState {
  Eigen::Isometry3d T_world_imu = Eigen::Isometry3d::Identity();
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();  // world frame, m/s
  ImuBias bias;

  NavState retract(const Vector15d& d) const;
};

// Gravity of a z-up world.
inline Eigen::Vector3d gravity_vector(double g = kStandardGravity) { return {0.0, 0.0, -g}; }

class ImuPreintegration {
 public:
  // Integrates with the measurements corrected by `bias_lin`, the bias the Jacobians are taken at.
  explicit ImuPreintegration(const ImuBias& bias_lin = {}, const ImuNoise& noise = {});

  // One measurement held over dt seconds.
  void integrate(const Eigen::Vector3d& gyro, const Eigen::Vector3d& accel, double dt);
  // The samples' signals from t0 to t1 (linearly interpolated at t0 and t1), each step with the
  // mean rate of its ends and their mean acceleration (the trapezoid rule): second order in the
  // sample period. Throws Error when the samples do not cover
  // [t0, t1] or are not in stamp order.
  void integrate(const std::vector<ImuSample>& samples, double t0, double t1);

  double dt() const { return dt_; }
  const Eigen::Matrix3d& delta_R() const { return dR_; }
  const Eigen::Vector3d& delta_v() const { return dv_; }
  const Eigen::Vector3d& delta_p() const { return dp_; }
  const Matrix9d& covariance() const { return cov_; }
  const ImuBias& bias_lin() const { return bias_lin_; }
  const ImuNoise& noise() const { return noise_; }
  // d(delta)/d(bias) at bias_lin.
  const Eigen::Matrix3d& dR_dbg() const { return dR_dbg_; }
  const Eigen::Matrix3d& dv_dbg() const { return dv_dbg_; }
  const Eigen::Matrix3d& dv_dba() const { return dv_dba_; }
  const Eigen::Matrix3d& dp_dbg() const { return dp_dbg_; }
  const Eigen::Matrix3d& dp_dba() const { return dp_dba_; }

  // The deltas for another bias, to first order (Forster Eq. 44).
  Eigen::Matrix3d corrected_delta_R(const ImuBias& bias) const;
  Eigen::Vector3d corrected_delta_v(const ImuBias& bias) const;
  Eigen::Vector3d corrected_delta_p(const ImuBias& bias) const;

  // The state at the end of the interval from the state at its start (bias kept).
  NavState predict(const NavState& start, const Eigen::Vector3d& gravity = gravity_vector()) const;

 private:
  // One step with bias-corrected measurements.
  void step(const Eigen::Vector3d& w, const Eigen::Vector3d& a, double dt);

  ImuBias bias_lin_;
  ImuNoise noise_;
  double dt_ = 0.0;
  Eigen::Matrix3d dR_ = Eigen::Matrix3d::Identity();
  Eigen::Vector3d dv_ = Eigen::Vector3d::Zero(), dp_ = Eigen::Vector3d::Zero();
  Matrix9d cov_ = Matrix9d::Zero();
  Eigen::Matrix3d dR_dbg_ = Eigen::Matrix3d::Zero(), dv_dbg_ = Eigen::Matrix3d::Zero(), dv_dba_ = Eigen::Matrix3d::Zero(),
                  dp_dbg_ = Eigen::Matrix3d::Zero(), dp_dba_ = Eigen::Matrix3d::Zero();
};

// The right Jacobian of SO(3) and its inverse.
Eigen::Matrix3d so3_right_jacobian(const Eigen::Vector3d& omega);
Eigen::Matrix3d so3_right_jacobian_inverse(const Eigen::Vector3d& omega);

}  // namespace gcmap
