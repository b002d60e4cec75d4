#include "gcmap/sim/simulator.hpp"

#include <array>
#include <cmath>
#include <sstream>

#include "gcmap/core/error.hpp"
#include "gcmap/sim/builders.hpp"
#include "gcmap/sim/rng.hpp"

namespace gcmap::sim {

namespace {

struct RealismKey {
  const char* name;
  bool RealismConfig::*flag;
};
constexpr std::array<RealismKey, 10> kRealismKeys{{{"motion_distortion", &RealismConfig::motion_distortion},
                                                   {"moving_objects", &RealismConfig::moving_objects},
                                                   {"labels", &RealismConfig::labels},
                                                   {"calibration", &RealismConfig::calibration},
                                                   {"range_noise", &RealismConfig::range_noise},
                                                   {"dropouts", &RealismConfig::dropouts},
                                                   {"mixed_pixels", &RealismConfig::mixed_pixels},
                                                   {"spurious", &RealismConfig::spurious},
                                                   {"curbs", &RealismConfig::curbs},
                                                   {"vegetation", &RealismConfig::vegetation}}};

std::unique_ptr<World> build_world(const Scenario& s, uint64_t seed, const RealismConfig& r,
                                   const std::vector<Eigen::Vector2f>& centerline) {
  std::unique_ptr<World> w;
  if (s.scene == SceneKind::grid_city) {
    Eigen::Vector2f lo = s.world_waypoints[0], hi = lo;
    for (const auto& p : s.world_waypoints) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
    const Eigen::Vector2i blo(std::floor(lo.x()) - 1, std::floor(lo.y()) - 1), bhi(std::ceil(hi.x()) + 1, std::ceil(hi.y()) + 1);
    const Eigen::Vector2f origin(blo.x() * s.block - s.block, blo.y() * s.block - s.block);
    w = std::make_unique<World>(s.terrain, origin, origin + ((bhi - blo).array() + 2).cast<float>().matrix() * s.block);
    build_city_blocks(*w, seed, s.block, blo, bhi, s.feature_poor, {s.tunnel_from, s.tunnel_to});
    if (r.curbs) add_sidewalks(*w, s.block, blo, bhi);
  } else {
    Eigen::Vector2f lo = centerline[0], hi = lo;
    for (const auto& p : centerline) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
    const float margin = s.scene == SceneKind::highway ? 150.f : 80.f;
    w = std::make_unique<World>(s.terrain, lo.array() - margin, hi.array() + margin);
    if (s.scene == SceneKind::highway) build_highway(*w, seed, centerline);
    else build_forest(*w, seed, centerline);
  }
  w->finalize();
  return w;
}

Traffic build_traffic(const Scenario& s, uint64_t seed, const std::vector<Eigen::Vector2f>& centerline) {
  if (s.scene == SceneKind::highway) return make_highway_traffic(seed, centerline);
  if (s.scene == SceneKind::forest) return make_trail_traffic(seed, centerline);
  Eigen::Vector2f lo = s.world_waypoints[0], hi = lo;
  for (const auto& p : s.world_waypoints) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
  return make_city_traffic(seed, s.block, Eigen::Vector2i(std::floor(lo.x()), std::floor(lo.y())),
                           Eigen::Vector2i(std::ceil(hi.x()), std::ceil(hi.y())));
}

}  // namespace

std::string default_sensor(const std::string& scenario) { return scenario == "handheld" ? "mid360" : "hdl64"; }

bool RealismConfig::any() const {
  for (const auto& k : kRealismKeys)
    if (this->*k.flag) return true;
  return false;
}

std::string RealismConfig::to_string() const {
  std::string out;
  for (const auto& k : kRealismKeys) {
    if (!(this->*k.flag)) continue;
    if (!out.empty()) out += ',';
    out += k.name;
  }
  return out.empty() ? "none" : out;
}

RealismConfig parse_realism(const std::string& text) {
  if (text == "all") return RealismConfig::all();
  RealismConfig r = RealismConfig::none();
  if (text == "none") return r;
  std::stringstream ss(text);
  std::string key;
  while (std::getline(ss, key, ',')) {
    bool known = false;
    for (const auto& k : kRealismKeys)
      if (key == k.name) r.*k.flag = true, known = true;
    if (!known) throw Error("--realism: unknown key '" + key + "' (expected all, none or keys such as motion_distortion,labels)");
  }
  return r;
}

Scenario make_scenario(const SimulationConfig& config) { return make_scenario(config.scenario, config.frames, config.route); }

Simulator::Simulator(const SimulationConfig& config)
    : config_(config),
      drive_seed_(config.route == 0 ? config.seed : hash_key(config.seed, 0x2047E, static_cast<uint64_t>(config.route))),
      scenario_(make_scenario(config)),
      realism_(config.realism        ? *config.realism
               : scenario_.realistic ? RealismConfig::all()
                                     : RealismConfig::none()),
      sensor_(sensor_model(config.sensor.empty() ? default_sensor(config.scenario) : config.sensor)),
      calibration_(make_calibration(sensor_, config.seed)) {
  if (!(config.noise >= 0.0) || config.noise > 1.0) throw Error("--noise: must be in [0, 1] m");
  const std::vector<Eigen::Vector2f> centerline = route_centerline(scenario_);
  world_ = build_world(scenario_, config.seed, realism_, centerline);
  trajectory_ = std::make_unique<Drive>(scenario_, *world_, drive_seed_);
  for (size_t k = 0; k < trajectory_->num_frames(); ++k) poses_.push_back(trajectory_->pose(static_cast<double>(k)));
  if (realism_.moving_objects) {
    traffic_ = build_traffic(scenario_, drive_seed_, centerline);
    add_parked_car_dynamics(*world_, drive_seed_, static_cast<float>(trajectory_->duration()));
  }
  set_porous_vegetation(*world_, config.seed, realism_.vegetation);
}

Eigen::Isometry3d Simulator::pose_at(size_t frame, double seconds) const {
  return trajectory_->pose(static_cast<double>(frame) + seconds / sensor_.period);
}

Eigen::Isometry3d Simulator::pose_at_time(double t) const { return trajectory_->pose(t / 0.1); }

}  // namespace gcmap::sim
