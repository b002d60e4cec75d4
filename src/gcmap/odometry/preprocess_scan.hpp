#pragma once
#include <string>

#include "gcmap/core/point_cloud.hpp"
#include "gcmap/graph/backend.hpp"

namespace gcmap {

// Each key's meaning, unit and valid range: the config table (mapping/config.cpp), docs/config.md.
struct PreprocessConfig {
  double min_range = 2.0;  // m: drops returns from the ego vehicle
  double max_range = 100.0;
  double downsample = 0.25;  // voxel size in m
  // Covariance estimation. Twenty, not ten: beyond 10-20 m a spinning sensor's ground rings lie
  // further apart than the grid, and ten neighbours lie on one ring, whose normal the range noise
  // decides (docs/pipeline.md, "Point covariances").
  int num_neighbors = 20;
  // Plane-like regularization of each covariance: eigenvalues (plane_epsilon, 1, 1). Smaller trusts
  // the normal more: exact planes gain; sparse scans, bent beams and a straight road lose.
  double plane_epsilon = 1e-3;
  // Beam elevation uncertainty added to each point's covariance (range x sigma along the beam's
  // vertical plane): a sensor with a per-beam elevation bias (factory calibration) makes far
  // ground lie off its plane by range x bias. 0 = off.
  double elevation_sigma_deg = 0.0;
  // A file of per-beam elevation offsets (`gcmap calibrate`, calibration/elevation_calibration.hpp)
  // applied to every raw scan; empty: none.
  std::string elevation_calibration;
  bool kitti_vertical_correction = true;  // 0.22 deg intrinsic correction, KITTI layouts only
  bool remove_dynamic_labels = true;      // SemanticKITTI moving classes, when labels/ exists
  // Motion compensation of scans with per-point times, by the motion the odometry registers over
  // the sweep (a velocity that changes linearly).
  bool deskew = true;
  // Each sweep deskewed again once the next one is registered, by the quadratic through the poses
  // on both sides of it (interpolated, no longer extrapolated), for the map and the odometry's model.
  bool redeskew = true;
  // Scans without per-point times from a spinning sensor: times from each point's azimuth
  // atan2(y, x), t = sweep_period * (the fraction of the turn since sweep_start_deg). The defaults
  // follow the point order of KITTI's HDL-64 files: each ring starts facing forward (+x, 0 deg) and
  // its azimuth increases, counter-clockwise seen from above.
  bool deskew_from_azimuth = false;
  double sweep_period = 0.1;  // s per turn
  double sweep_start_deg = 0.0;
  bool sweep_clockwise = false;
};

// Range filter, voxel downsampling and k-neighbour covariances of one raw scan; the covariances on
// `backend` when given (a GPU's), else on the CPU.
PointCloud preprocess_scan(const PointCloud& raw, const PreprocessConfig& config, LinearizationBackend* backend = nullptr);

}  // namespace gcmap
