#pragma once
// A simulated IMU rigidly attached to the LiDAR. The drive's poses are piecewise (a polyline and a
// piecewise-linear speed profile), so the IMU is derived from a smooth trajectory through the IMU
// poses at knots, T_world_imu(t_k) = T_world_lidar(t_k) T_lidar_imu: positions by quintic Hermite
// segments (position, velocity and acceleration continuous), rotations by R_k exp(phi(tau)) with a
// cubic Hermite phi (angular velocity continuous); knot velocities and accelerations from central
// differences. The samples are the exact derivatives of that trajectory. Knots at the frame stamps
// only would leave the IMU blind to how the motion changes within a sweep (it would know no more
// than 10 Hz poses do): imu_trajectory puts ten knots in each frame, so that the IMU follows the
// LiDAR's own in-sweep poses closely.
#include <Eigen/Geometry>
#include <cstdint>
#include <string>
#include <vector>

#include "gcmap/core/imu_sample.hpp"
#include "gcmap/graph/imu_preintegration.hpp"

namespace gcmap::sim {

struct ImuSimConfig {
  double rate = 200.0;  // Hz
  bool noise = true;    // white noise and bias random walk from `density`, initial biases from the seed
  ImuNoise density;
  Eigen::Isometry3d T_lidar_imu = default_T_lidar_imu();
  // The IMU's clock runs ahead of the LiDAR's: an IMU sample of true time t is stamped t + time_offset.
  double time_offset = 0.0;  // s
  // A few centimetres and no rotation, as a LiDAR's built-in IMU.
  static Eigen::Isometry3d default_T_lidar_imu();
};

// The smooth IMU trajectory through frame poses `T_world_lidar` taken every `period` seconds from 0.
class ImuTrajectory {
 public:
  ImuTrajectory(const std::vector<Eigen::Isometry3d>& T_world_lidar, double period, const Eigen::Isometry3d& T_lidar_imu);
  double duration() const { return period_ * (R_.size() - 1); }
  NavState state(double t) const;  // pose, world velocity; zero biases
  // Gyro and specific force in the IMU frame at true time t (gravity along -z of the world).
  ImuSample measure(double t) const;

 private:
  // Segment k and tau in [0, 1] of time t.
  std::pair<size_t, double> locate(double t) const;
  double period_;
  std::vector<Eigen::Matrix3d> R_;
  std::vector<Eigen::Vector3d> p_, v_, a_, w_;       // knot positions, velocities, accelerations, body rates
  std::vector<Eigen::Vector3d> phi_end_, dphi_end_;  // per segment: log(R_k^T R_k+1), phi'(1)
};

class Simulator;
// The IMU trajectory of a simulated drive: knots every 0.01 s up to its last frame's stamp.
ImuTrajectory imu_trajectory(const Simulator& sim, const Eigen::Isometry3d& T_lidar_imu);

struct SimulatedImu {
  std::vector<ImuSample> samples;  // stamped on the IMU's clock
  std::vector<ImuSample> bias;     // the true biases at each sample: gyro, accel
};

// Samples from 0 to the last frame at config.rate, with noise and bias drawn from `seed`.
SimulatedImu simulate_imu(const ImuTrajectory& trajectory, const ImuSimConfig& config, uint64_t seed);

}  // namespace gcmap::sim
