#pragma once
// The odometry's LiDAR-inertial state: pose, velocity and IMU biases at each registered sweep,
// estimated by a fixed-lag smoother over the last two sweeps (the older one marginalized into a
// prior) from a preintegrated IMU factor, the bias random walk and the registration's pose weighted
// by its Hessian (less where the IMU's prediction contradicts it). It predicts where the next sweep
// starts, translation included; its pose is the frame's, so the IMU carries what a registration
// cannot see (a tunnel) or place (a fast turn).
// Gravity is found in the odometry's own frame (the first scan's) from the first registered second
// (the map frame is unchanged), and its direction stays an unknown of the smoother: the
// odometry's roll and pitch wander from the first scan's, and gravity held fixed in its frame would
// read each wander as an acceleration.
#include <Eigen/Geometry>
#include <optional>
#include <vector>

#include "gcmap/core/imu_sample.hpp"
#include "gcmap/graph/gravity_window.hpp"
#include "gcmap/graph/imu_factors.hpp"
#include "gcmap/graph/imu_preintegration.hpp"

namespace gcmap {

// A registration's Hessian (graph/backend.hpp, [rotation, translation]) as the information of the
// pose it found: a quarter of it, its degenerate translations dropped, the others' information
// multiplied by their share of the best one's.
Matrix6d registration_information(const Matrix6d& hessian);

class InertialTrack {
 public:
  explicit InertialTrack(const ImuConfig& config);

  // A sample on the IMU's clock and in its frame; stamps increasing.
  void add(const ImuSample& sample);
  // The LiDAR's pose at `time` (LiDAR clock), registered with `information` (6x6 over [rotation,
  // translation] of T_world_lidar), or null information: placed otherwise, nothing measured. Times
  // increasing.
  void observe(double time, const Eigen::Isometry3d& T_world_lidar, const Matrix6d* information);
  // The LiDAR's pose at `time`, propagated by the IMU from the last state; empty before the state
  // is known or beyond the samples.
  std::optional<Eigen::Isometry3d> predict(double time) const;
  // Drops the state (the odometry starts again); gravity is found again.
  void reset();

  bool ready() const { return state_.has_value(); }
  const NavState& state() const { return *state_; }            // when ready
  const Eigen::Vector3d& gravity() const { return gravity_; }  // odometry frame, m/s^2
  const Eigen::Isometry3d& T_imu_lidar() const { return T_imu_lidar_; }
  // The biases of the last state there was (kept through a reset), for the report.
  const std::optional<ImuBias>& last_bias() const { return last_bias_; }
  // How far (deg) that state's gravity had turned from where its start found it: the odometry's
  // roll and pitch wander, for the report.
  const std::optional<double>& last_gravity_turn_deg() const { return last_gravity_turn_deg_; }

 private:
  bool covers(double t0, double t1) const;
  // From the registered poses of the last second and the samples: gravity (a gravity window over
  // them, graph/gravity_window.hpp) and the last velocity.
  bool initialize();
  void update(double time, const Eigen::Isometry3d* T_world_lidar, const Matrix6d* information);

  ImuConfig config_;
  Eigen::Isometry3d T_imu_lidar_;
  std::vector<ImuSample> samples_;    // LiDAR clock, IMU frame
  std::vector<OdometryFrame> start_;  // registered in a row, until the state is known
  std::optional<NavState> state_;
  double state_time_ = 0.0;
  // Of [gravity tilt (2: about two axes across gravity_), state_ (15)].
  Eigen::Matrix<double, 17, 17> information_ = Eigen::Matrix<double, 17, 17>::Zero();
  Eigen::Vector3d gravity_ = Eigen::Vector3d::Zero(), start_gravity_ = Eigen::Vector3d::Zero();
  std::optional<ImuBias> last_bias_;
  std::optional<double> last_gravity_turn_deg_;
};

}  // namespace gcmap
