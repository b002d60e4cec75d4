#pragma once
// Motion compensation of a LiDAR sweep: each point, measured at cloud.times[i] (s after the sweep's
// reference instant 0), is moved into the sensor frame at time 0, assuming a constant velocity, or
// one that changes linearly, over the sweep. Covariances (when present) are rotated with their
// points; times are kept.
#include <Eigen/Geometry>
#include <vector>

#include "gcmap/core/point_cloud.hpp"
#include "gcmap/core/se3.hpp"

namespace gcmap {

// `velocity` [omega; rho] (rad/s, m/s) in the sensor frame: T_0_t = exp(t * velocity).
void deskew(PointCloud& cloud, const Vector6d& velocity);

// The velocity changing linearly over the sweep, as a quadratic in the tangent space at the instant
// `anchor` (s): T_anchor_t = exp(u * velocity + u^2 / 2 * acceleration) with u = t - anchor, and
// T_0_t = T_anchor_0^-1 T_anchor_t. At anchor 0, velocity is the one at time 0. (A curve fitted
// around a registered pose at the sweep's mean point time keeps that pose exact.)
void deskew(PointCloud& cloud, const Vector6d& velocity, const Vector6d& acceleration, double anchor = 0.0);

// T_begin_end: the sensor pose at time `sweep_duration` in the frame at time 0 (for example the
// motion predicted between two scans, scaled to the sweep). No-op without times.
void deskew(PointCloud& cloud, const Eigen::Isometry3d& T_begin_end, double sweep_duration);

// Sensor poses T_0_t at t0 + k step, k = 0 .. T.size()-1, for a motion known as samples (an IMU's);
// between two of them a pose is the linear blend of their rotations and translations (keep steps
// small: 1 ms), beyond them the nearest is held.
struct SweepPoses {
  double t0 = 0.0, step = 1e-3;
  std::vector<Eigen::Isometry3d> T;
  Eigen::Isometry3d at(double t) const;
};
void deskew(PointCloud& cloud, const SweepPoses& poses);

}  // namespace gcmap
