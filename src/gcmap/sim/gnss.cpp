#include "gcmap/sim/gnss.hpp"

#include <cmath>

#include "gcmap/core/error.hpp"
#include "gcmap/sim/rng.hpp"

namespace gcmap::sim {

GnssQuality parse_gnss_quality(const std::string& text, const std::string& key) {
  if (text == "rtk") return GnssQuality::rtk;
  if (text == "float") return GnssQuality::float_solution;
  if (text == "single") return GnssQuality::single_point;
  throw Error(key + ": expected rtk, float or single, got '" + text + "'");
}

const char* to_string(GnssQuality quality) {
  switch (quality) {
    case GnssQuality::rtk: return "rtk";
    case GnssQuality::float_solution: return "float";
    case GnssQuality::single_point: return "single";
  }
  return "?";
}

GnssNoise gnss_noise(GnssQuality quality) {
  switch (quality) {
    case GnssQuality::rtk: return {0.015, 0.025, 0.0};
    case GnssQuality::float_solution: return {0.3, 0.5, 10.0};
    case GnssQuality::single_point: return {2.0, 3.0, 30.0};
  }
  return {};
}

namespace {

// A structure (not a tree's canopy) within 200 m straight above the antenna.
bool sky_blocked(const World& world, const Eigen::Vector3d& antenna) {
  Hit hit;
  const bool any = world.raycast(antenna.cast<float>(), Eigen::Vector3f::UnitZ(), 200.f, hit);
  return any && hit.label != kVegetation;
}

// The receiver's error: per axis phi e + sqrt(1 - phi^2) sigma n (stationary at sigma).
class GaussMarkov {
 public:
  GaussMarkov(const GnssNoise& n, double dt, uint64_t seed)
      : sigma_(n.sigma_horizontal, n.sigma_horizontal, n.sigma_vertical),
        phi_(n.correlation_s > 0 ? std::exp(-dt / n.correlation_s) : 0.0),
        rng_(seed) {
    for (int a = 0; a < 3; ++a) e_[a] = sigma_[a] * rng_.normal();
  }
  Eigen::Vector3d next() {
    const double k = std::sqrt(1.0 - phi_ * phi_);
    for (int a = 0; a < 3; ++a) e_[a] = phi_ * e_[a] + k * sigma_[a] * rng_.normal();
    return e_;
  }
  Rng& rng() { return rng_; }

 private:
  Eigen::Vector3d sigma_, e_;
  double phi_;
  Rng rng_;
};

Eigen::Vector3d multipath(Rng& rng) {
  const double angle = rng.uniform(0.f, 6.2831853f), r = rng.uniform(3.f, 15.f);
  return {r * std::cos(angle), r * std::sin(angle), rng.uniform(-2.f, 8.f)};
}

}  // namespace

SimulatedGnss simulate_gnss(const Simulator& sim, const GnssSimConfig& c, uint64_t seed) {
  if (!(c.rate > 0.0)) throw Error("simulate_gnss: the rate must be positive");
  const GnssNoise noise = gnss_noise(c.quality);
  GaussMarkov error(noise, 1.0 / c.rate, hash_key(seed, 0x676e7373));
  const Eigen::Isometry3d T_ecef_world = T_ecef_enu(c.origin);
  const double end = 0.1 * double(sim.num_frames() - 1);
  SimulatedGnss out;
  for (long k = 0; k / c.rate <= end + 1e-9; ++k) {
    const double t = k / c.rate;
    const size_t frame = std::min(static_cast<size_t>(std::floor(t * 10.0 + 1e-9)), sim.num_frames() - 1);
    const Eigen::Vector3d antenna = sim.pose_at(frame, t - 0.1 * double(frame)) * c.lever_arm;
    Eigen::Vector3d e = error.next();  // drawn for every epoch: an outage leaves the rest as it was
    const bool outlier = error.rng().uniform() < c.outlier_fraction;
    if (outlier) e += multipath(error.rng());
    if (c.outage && t >= c.outage->first && t < c.outage->second) {
      ++out.in_outage;
      out.no_fix_stamps.push_back(t);
      continue;
    }
    if (sky_blocked(sim.world(), antenna)) {
      ++out.blocked;
      out.no_fix_stamps.push_back(t);
      continue;
    }
    out.outliers += outlier;
    const Eigen::Vector3d sigma(noise.sigma_horizontal, noise.sigma_horizontal, noise.sigma_vertical);
    out.fixes.push_back({t, geodetic_from_ecef(T_ecef_world * (antenna + e)), sigma});
    out.truth_enu.push_back(antenna);
  }
  return out;
}

}  // namespace gcmap::sim
