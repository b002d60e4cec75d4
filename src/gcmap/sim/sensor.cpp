#include "gcmap/sim/sensor.hpp"

#include <cmath>

#include "gcmap/core/error.hpp"
#include "gcmap/sim/rng.hpp"

namespace gcmap::sim {

namespace {
constexpr double kDeg = M_PI / 180.0;
// Rosette: two prisms turning at incommensurate rates; the beam deflection is the sum of two
// counter-rotating vectors, which draws petals that precess from sweep to sweep.
constexpr double kPrismHz1 = 73.13, kPrismHz2 = 51.71;
constexpr double kHalfFovH = 35.2 * kDeg, kHalfFovV = 38.6 * kDeg;
// Mid-360: the elevation's two oscillations (Hz).
constexpr double kMidHz1 = 173.3, kMidHz2 = 61.7;
}  // namespace

Eigen::Vector3f SensorModel::direction(int group, int ray, double sweep_start, float elevation_bias) const {
  if (pattern == ScanPattern::spinning) {
    const float az = 2.f * static_cast<float>(M_PI) * group / azimuth_steps;
    const float el = elevations_deg[ray] * static_cast<float>(M_PI) / 180.f + elevation_bias;
    return {std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el)};
  }
  if (pattern == ScanPattern::mid360) {
    // Four lasers a quarter turn apart, one turn per sweep; the elevation follows two
    // incommensurate oscillations, so successive sweeps fill the field of view differently.
    const double t = sweep_start + period * static_cast<double>(group) / rosette_firings;
    const double az = 2.0 * M_PI * (static_cast<double>(group) / rosette_firings + 0.25 * ray);
    const double w = 0.5 + 0.5 * (0.55 * std::sin(2.0 * M_PI * kMidHz1 * t + 1.3 * ray) +
                                  0.45 * std::sin(2.0 * M_PI * kMidHz2 * t + 2.1 * ray));
    const double el = (-7.0 + 59.0 * w) * kDeg + elevation_bias;
    return Eigen::Vector3d(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el)).cast<float>();
  }
  // The six lasers sit side by side and fire together, each a little ahead in the pattern.
  const double t = sweep_start + period * static_cast<double>(group) / rosette_firings + ray * 2.1e-4;
  const double a1 = 2.0 * M_PI * kPrismHz1 * t, a2 = 2.0 * M_PI * kPrismHz2 * t;
  const double az = kHalfFovH * 0.5 * (std::cos(a1) + std::cos(a2)) + (ray - 2.5) * 0.08 * kDeg;
  const double el = kHalfFovV * 0.5 * (std::sin(a1) - std::sin(a2)) + elevation_bias;
  return Eigen::Vector3d(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el)).cast<float>();
}

SensorModel sensor_model(const std::string& name) {
  SensorModel s;
  s.name = name;
  if (name == "hdl64") {
    // HDL-64E: upper block +2 to -8.33 deg in 1/3 deg steps, lower block -8.83 to -24.33 in 1/2.
    for (int k = 0; k < 32; ++k) s.elevations_deg.push_back(2.0f - k / 3.0f);
    for (int k = 0; k < 32; ++k) s.elevations_deg.push_back(-8.83f - k * 0.5f);
    s.azimuth_steps = 1800;
  } else if (name == "vlp16") {
    for (int k = 0; k < 16; ++k) s.elevations_deg.push_back(-15.0f + 2.0f * k);
    s.azimuth_steps = 1800;
    s.max_range = 100.0f;
  } else if (name == "os1-64") {
    for (int k = 0; k < 64; ++k) s.elevations_deg.push_back(-22.5f + 45.0f * k / 63.0f);
    s.azimuth_steps = 1024;
  } else if (name == "os1-128") {
    for (int k = 0; k < 128; ++k) s.elevations_deg.push_back(-22.5f + 45.0f * k / 127.0f);
    s.azimuth_steps = 1024;
  } else if (name == "avia") {
    s.pattern = ScanPattern::rosette;  // 240,000 points/s: 6 lasers x 40 kHz
    s.min_range = 1.0f;
    s.max_range = 190.0f;
  } else if (name == "mid360") {
    s.pattern = ScanPattern::mid360;  // 200,000 points/s: 4 lasers x 50 kHz
    s.rosette_firings = 5000;
    s.rosette_lasers = 4;
    s.min_range = 0.1f;
    s.max_range = 70.0f;
  } else {
    throw Error("--sensor: expected hdl64, vlp16, os1-64, os1-128, avia or mid360, got '" + name + "'");
  }
  return s;
}

Calibration make_calibration(const SensorModel& sensor, uint64_t seed) {
  Calibration c;
  Rng r(hash_key(seed, 0xCA1));
  for (int b = 0; b < sensor.rays_per_group(); ++b) {
    const float s1 = r.uniform() < 0.5f ? -1.f : 1.f, s2 = r.uniform() < 0.5f ? -1.f : 1.f;
    c.elevation_bias_rad.push_back(s1 * r.uniform(0.1f, 0.2f) * static_cast<float>(kDeg));
    c.range_offset_m.push_back(s2 * r.uniform(0.01f, 0.03f));
  }
  return c;
}

}  // namespace gcmap::sim
