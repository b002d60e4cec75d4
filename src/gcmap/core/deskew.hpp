#pragma once
// Motion compensation of a LiDAR sweep: each point, measured at cloud.times[i] (s after the sweep's
// reference instant 0), is moved into the sensor frame at time 0, assuming a constant velocity, or
// one that changes linearly, over the sweep. Covariances (when present) are rotated with their
// points; times are kept.
#include <Eigen/Geometry>

#include "gcmap/core/point_cloud.hpp"
#include "gcmap/core/se3.hpp"

namespace gcmap {

// `velocity` [omega; rho] (rad/s, m/s) in the sensor frame: T_0_t = exp(t * velocity).
void deskew(PointCloud& cloud, const Vector6d& velocity);

// The velocity changing linearly over the sweep: velocity at time 0 plus t * acceleration,
// T_0_t = exp(t * velocity + t^2 / 2 * acceleration).
void deskew(PointCloud& cloud, const Vector6d& velocity, const Vector6d& acceleration);

// T_begin_end: the sensor pose at time `sweep_duration` in the frame at time 0 (for example the
// motion predicted between two scans, scaled to the sweep). No-op without times.
void deskew(PointCloud& cloud, const Eigen::Isometry3d& T_begin_end, double sweep_duration);

}  // namespace gcmap
