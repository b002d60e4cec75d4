#pragma once
// A simulated GNSS receiver on the drive: the world frame (poses_world.txt) is the local ENU frame
// (x east, y north, z up) at a geodetic origin, and fixes of the antenna (a lever arm from the
// LiDAR) are written as gnss.txt (io/gnss_io.hpp). Errors per axis are a first-order Gauss-Markov
// process (white for RTK) of the quality's sigma; a fraction of fixes carries a multipath error of
// metres; no fix where a structure is straight above the antenna, nor in a given outage window.
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "gcmap/io/gnss_io.hpp"
#include "gcmap/sim/simulator.hpp"

namespace gcmap::sim {

enum class GnssQuality { rtk, float_solution, single_point };
// "rtk", "float", "single"; Error naming `key` otherwise.
GnssQuality parse_gnss_quality(const std::string& text, const std::string& key);
const char* to_string(GnssQuality quality);

// One standard deviation per axis, and the correlation time of the error (0: white).
struct GnssNoise {
  double sigma_horizontal = 0.0, sigma_vertical = 0.0, correlation_s = 0.0;
};
// rtk: 1.5 cm / 2.5 cm, white; float: 0.3 m / 0.5 m, 10 s; single: 2 m / 3 m, 30 s.
GnssNoise gnss_noise(GnssQuality quality);

struct GnssSimConfig {
  double rate = 10.0;  // Hz
  GnssQuality quality = GnssQuality::rtk;
  double outlier_fraction = 0.0;                        // multipath: 3-15 m horizontally in a random direction, -2 to 8 m up
  Eigen::Vector3d lever_arm = Eigen::Vector3d::Zero();  // m, the antenna in the LiDAR frame
  Geodetic origin{48.137154, 11.576124, 520.0};         // of the world frame (Munich)
  std::optional<std::pair<double, double>> outage;      // s: no fixes in [first, second)
};

struct SimulatedGnss {
  std::vector<GnssFix> fixes;
  std::vector<Eigen::Vector3d> truth_enu;  // per fix: the antenna's true position
  std::vector<double> no_fix_stamps;       // epochs in the outage or under a roof: a receiver reports NO_FIX
  size_t outliers = 0, blocked = 0, in_outage = 0;
};

// Fixes from 0 to the last frame's stamp (frames 0.1 s apart), drawn from `seed`.
SimulatedGnss simulate_gnss(const Simulator& sim, const GnssSimConfig& config, uint64_t seed);

}  // namespace gcmap::sim
