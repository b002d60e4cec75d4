#pragma once
// Scenarios (routes, worlds, speed) and the vehicle's trajectory along a route.
#include <Eigen/Geometry>
#include <string>
#include <vector>

#include "gcmap/sim/world.hpp"

namespace gcmap::sim {

enum class SceneKind { grid_city, highway, forest };

struct Scenario {
  std::string name;
  SceneKind scene = SceneKind::grid_city;
  float block = 50.f;                      // street spacing in m (the unit of the waypoints)
  std::vector<Eigen::Vector2f> waypoints;  // in blocks, along streets: the route driven
  // Route 0's waypoints: the street grid (world, traffic) that every route of the scenario shares.
  std::vector<Eigen::Vector2f> world_waypoints;
  int frames = 0;  // constant speed: frames spread evenly over the route; else 0 = the whole drive
  bool feature_poor = false;
  // Blocks x in [tunnel_from, tunnel_to): one unbroken flat wall on each side of the streets along
  // x, across the cross streets (a tunnel-like canyon, degenerate along it).
  int tunnel_from = 0, tunnel_to = 0;
  bool realistic = false;  // realism on by default, traffic, sidewalks, a speed profile
  float corner_radius = 9.f, lane_offset = 2.f;
  // Speed profile (realistic scenarios): cruise speed drawn per 150 m within [cruise_min,
  // cruise_max], slower in curves, a stop before every `stop_every`-th waypoint.
  float cruise_min = 0.f, cruise_max = 0.f, lateral_accel = 2.5f;
  int stop_every = 0;
  bool rest_at_ends = true;  // starts from and ends in a stop
  float sensor_height = 1.73f;  // m above the ground
  bool handheld = false;        // a walking person's gait and glances on top of the route (Drive::pose)
  Terrain terrain;
  std::string description;
};
// loop, small, corridor, tunnel (evenly spaced frames, no realism by default), city, highway, forest,
// handheld.
// `frames` > 0 overrides the frame count (for realistic scenarios: the first `frames` frames).
// `route` > 0 drives another route through the same world (city, small and loop have more than one),
// starting elsewhere and overlapping route 0 in part.
Scenario make_scenario(const std::string& name, int frames, int route = 0);
// How many routes the scenario has (1 for those without alternatives).
int num_routes(const std::string& name);

// The route as a dense polyline (5 cm steps) with rounded corners, on the road's centre line;
// `corner_starts[k]` is the index where the curve at waypoint k begins.
std::vector<Eigen::Vector2f> route_centerline(const Scenario& s, std::vector<size_t>* corner_starts = nullptr);
// The same shifted by `offset` to the right of the direction of travel.
std::vector<Eigen::Vector2f> shifted_right(const std::vector<Eigen::Vector2f>& line, float offset);

// The sensor's motion along the lane: its pose at any time, following the terrain.
class Drive {
 public:
  Drive(const Scenario& s, const World& world, uint64_t seed);
  size_t num_frames() const { return num_frames_; }
  double length() const { return length_; }
  // Of the whole drive, also when only its first frames are simulated.
  double duration() const { return even_ ? num_frames_ * 0.1 : knot_t_.back(); }
  // Pose at `frame` + a fraction of a frame period (frames are 0.1 s apart).
  Eigen::Isometry3d pose(double frame) const;
  const std::vector<Eigen::Vector2f>& lane() const { return lane_; }

 private:
  double arclength(double frame) const;
  // The handheld sensor's motion relative to the walked route at time t: gait bounce and sway,
  // and glances aside (a fast turn of the device there and back).
  Eigen::Isometry3d gait(double t) const;
  void speed_profile(const Scenario& s, const std::vector<size_t>& corner_starts, uint64_t seed);

  const World& world_;
  float sensor_height_;
  bool handheld_;
  uint64_t seed_;
  std::vector<Eigen::Vector2f> lane_;
  std::vector<double> arc_;
  double length_ = 0.0;
  size_t num_frames_ = 0;
  bool even_ = true;                     // constant speed: frames evenly spaced along the route
  // Speed profile: arc length and speed at times; constant acceleration between knots, so that the
  // speed is continuous (an IMU would feel a speed that steps).
  std::vector<double> knot_t_, knot_s_, knot_v_;
};

}  // namespace gcmap::sim
