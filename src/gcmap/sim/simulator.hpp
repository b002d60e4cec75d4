#pragma once
#include <Eigen/Geometry>
#include <string>
#include <vector>

#include "gcmap/core/point_cloud.hpp"
#include "gcmap/sim/world.hpp"

namespace gcmap::sim {

// A spinning multi-beam LiDAR; one scan is captured at one pose (no motion distortion).
struct SensorModel {
  std::string name;
  std::vector<float> elevations_deg;
  int azimuth_steps = 1800;
  float min_range = 2.0f, max_range = 120.0f;
  float dropout = 0.01f;  // fraction of returns lost
};
SensorModel sensor_model(const std::string& name);  // hdl64, vlp16, os1-64

struct SimulationConfig {
  std::string scenario = "loop";  // loop, small, corridor
  int frames = 0;                 // 0: the scenario's default
  uint64_t seed = 1;
  std::string sensor = "hdl64";
  double noise = 0.02;  // range noise sigma in m
};

struct Scenario {
  std::string name;
  float block = 50.f;                       // street spacing in m
  std::vector<Eigen::Vector2f> waypoints;   // in blocks, along streets
  int frames = 0;
  bool feature_poor = false;
  std::string description;
};
Scenario make_scenario(const SimulationConfig& config);

class Simulator {
 public:
  explicit Simulator(const SimulationConfig& config);
  size_t num_frames() const { return poses_.size(); }
  // World poses of the sensor at each frame.
  const std::vector<Eigen::Isometry3d>& poses() const { return poses_; }
  const Scenario& scenario() const { return scenario_; }
  double path_length() const { return length_; }
  // Deterministic for (seed, frame). Points in the sensor frame, with intensity.
  PointCloud scan(size_t frame) const;

 private:
  SimulationConfig config_;
  Scenario scenario_;
  SensorModel sensor_;
  World world_;
  std::vector<Eigen::Isometry3d> poses_;
  double length_ = 0.0;
};

// Writes DIR/velodyne/NNNNNN.bin, poses.txt (sensor frame, first pose identity), times.txt and
// scenario.json. Returns the number of points written.
size_t write_simulation(const std::string& dir, const SimulationConfig& config, bool quiet = true);

}  // namespace gcmap::sim
