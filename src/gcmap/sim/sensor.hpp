#pragma once
// LiDAR models: spinning multi-beam sensors (a column of beams fired at once, columns swept over
// 360 degrees), a Livox-Avia-like solid-state sensor (six lasers steered by a pair of rotating
// prisms along a rosette that never repeats and fills the field of view over time) and a
// Livox-Mid-360-like one (four lasers swept around 360 degrees of azimuth while their elevation
// wanders over -7 to +52 degrees along a pattern that never repeats).
#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

namespace gcmap::sim {

enum class ScanPattern { spinning, rosette, mid360 };

struct SensorModel {
  std::string name;
  ScanPattern pattern = ScanPattern::spinning;
  std::vector<float> elevations_deg;  // spinning: one per beam
  int azimuth_steps = 1800;           // spinning: columns per sweep
  int rosette_firings = 4000;         // rosette: firings of all lasers per sweep
  int rosette_lasers = 6;
  float min_range = 2.0f, max_range = 120.0f;
  float dropout = 0.01f;  // fraction of returns lost
  float period = 0.1f;    // sweep period in s

  // A firing group is fired at one instant: a column of a spinning sensor, one pulse of every
  // laser of the rosette sensor.
  int groups() const { return pattern == ScanPattern::spinning ? azimuth_steps : rosette_firings; }
  int rays_per_group() const {
    return pattern == ScanPattern::spinning ? static_cast<int>(elevations_deg.size()) : rosette_lasers;
  }
  bool non_repetitive() const { return pattern != ScanPattern::spinning; }
  // Unit direction in the sensor frame of ray `ray` of group `group`; `sweep_start` is the absolute
  // time of the sweep (the rosette continues across sweeps); `elevation_bias` in radians.
  Eigen::Vector3f direction(int group, int ray, double sweep_start, float elevation_bias = 0.f) const;
};

// hdl64, vlp16, os1-64, os1-128, avia, mid360. Throws Error naming --sensor otherwise.
SensorModel sensor_model(const std::string& name);

// A factory calibration that is slightly off: per beam a fixed elevation bias (0.1 to 0.2 deg,
// either sign) and range offset (1 to 3 cm, either sign). Deterministic in the seed.
struct Calibration {
  std::vector<float> elevation_bias_rad, range_offset_m;
};
Calibration make_calibration(const SensorModel& sensor, uint64_t seed);

}  // namespace gcmap::sim
