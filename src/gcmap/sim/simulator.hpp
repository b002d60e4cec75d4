#pragma once
#include <Eigen/Geometry>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "gcmap/core/point_cloud.hpp"
#include "gcmap/sim/scenario.hpp"
#include "gcmap/sim/sensor.hpp"
#include "gcmap/sim/traffic.hpp"
#include "gcmap/sim/world.hpp"

namespace gcmap::sim {

// What makes the simulated world hard in the ways real drives are. Keys as in --realism.
struct RealismConfig {
  bool motion_distortion = true;  // each firing at the pose of its own time within the sweep
  bool moving_objects = true;     // traffic, cyclists, pedestrians; parked cars come and go
  bool labels = true;             // SemanticKITTI labels/NNNNNN.label
  bool calibration = true;        // per-beam elevation bias and range offset
  bool range_noise = true;        // noise sigma grows with range
  bool dropouts = true;           // weak returns lost: grazing incidence, dark surfaces, far
  bool mixed_pixels = true;       // returns between the two surfaces at depth edges
  bool spurious = true;           // a few returns from nowhere
  bool curbs = true;              // raised sidewalks
  bool vegetation = true;         // porous canopies: partial returns

  static RealismConfig all() { return {}; }
  static RealismConfig none() { return {false, false, false, false, false, false, false, false, false, false}; }
  bool any() const;
  std::string to_string() const;  // the enabled keys, comma-separated, or "none"
};
// "all", "none" or a comma-separated list of keys (motion_distortion, moving_objects, labels,
// calibration, range_noise, dropouts, mixed_pixels, spurious, curbs, vegetation) to enable.
RealismConfig parse_realism(const std::string& text);

struct SimulationConfig {
  std::string scenario = "loop";  // loop, small, corridor, city, highway, forest
  int frames = 0;                 // 0: the scenario's default
  uint64_t seed = 1;
  // Which of the scenario's routes through the world of `seed` (see make_scenario): the noise,
  // the speed profile and the moving objects differ per route, the static world does not.
  int route = 0;
  std::string sensor;  // empty: the scenario's (default_sensor)
  double noise = 0.02;  // range noise sigma in m (at about 20 m with range_noise)
  // Unset: the scenario's default (everything for city, highway and forest; nothing for loop,
  // small and corridor, whose output stays as it always was).
  std::optional<RealismConfig> realism;
};

Scenario make_scenario(const SimulationConfig& config);
// The sensor a scenario is simulated with unless told: mid360 for handheld, hdl64 otherwise.
std::string default_sensor(const std::string& scenario);

class Simulator {
 public:
  explicit Simulator(const SimulationConfig& config);
  size_t num_frames() const { return poses_.size(); }
  // World poses of the sensor at each frame's stamp (the start of its sweep); the world frame is
  // the same for every route of a scenario and seed.
  const std::vector<Eigen::Isometry3d>& poses() const { return poses_; }
  // World pose of the sensor `seconds` after the stamp of `frame`.
  Eigen::Isometry3d pose_at(size_t frame, double seconds) const;
  // World pose of the sensor at time t (s since frame 0's stamp; frames are 0.1 s apart).
  Eigen::Isometry3d pose_at_time(double t) const;
  const Scenario& scenario() const { return scenario_; }
  const SensorModel& sensor() const { return sensor_; }
  const RealismConfig& realism() const { return realism_; }
  const World& world() const { return *world_; }
  const Traffic& traffic() const { return traffic_; }
  double path_length() const { return trajectory_->length(); }
  // Deterministic for (seed, frame). Points in the sensor frame at their firing time, with
  // intensity; with distortion, times (s after the stamp); with labels, SemanticKITTI labels
  // (class | instance << 16). `ray_ids` (optional): group * rays_per_group + ray of each point.
  PointCloud scan(size_t frame, std::vector<uint32_t>* ray_ids = nullptr) const;

 private:
  struct Rays;
  void cast_group(size_t frame, int group, const std::vector<ActiveMover>& movers, Rays& out) const;
  void mix_depth_edges(size_t frame, Rays& rays) const;

  SimulationConfig config_;
  uint64_t drive_seed_;  // of what differs per route (noise, speeds, movers); route 0: the seed
  Scenario scenario_;
  RealismConfig realism_;
  SensorModel sensor_;
  Calibration calibration_;
  std::unique_ptr<World> world_;
  std::unique_ptr<Drive> trajectory_;
  Traffic traffic_;
  std::vector<Eigen::Isometry3d> poses_;
};

// Writes DIR/velodyne/NNNNNN.bin, poses.txt (sensor frame at each stamp, first pose identity),
// poses_world.txt (the same in the world frame that all routes share), times.txt, scenario.json and, with the realism that makes
// them, point_times/NNNNNN.bin (float32 seconds after the stamp, one per point) and labels/NNNNNN.label. Returns the number of
// points.
size_t write_simulation(const std::string& dir, const SimulationConfig& config, bool quiet = true);

}  // namespace gcmap::sim
