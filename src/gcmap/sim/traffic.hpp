#pragma once
// Moving objects (cars, trucks, cyclists, pedestrians), each following its own path at its own
// speed, so they appear at different places in different scans.
#include <Eigen/Geometry>
#include <cstdint>
#include <vector>

#include "gcmap/sim/world.hpp"

namespace gcmap::sim {

struct Mover {
  uint32_t path = 0;
  float offset = 0.f;           // lateral, positive to the right of the path's direction
  float s0 = 0.f, speed = 0.f;  // arc length at time 0 (wraps around the path), m/s
  Eigen::Vector3f half{2.2f, 0.9f, 0.75f};
  float reflectivity = 0.5f;
  uint16_t label = kMovingCar;
};

struct MoverState {
  Eigen::Vector3f center, velocity;
  float yaw = 0.f;
};

// A mover as seen during one sweep: its state at the sweep start, moving linearly, and the
// azimuth window (sensor frame) where rays can hit it.
struct ActiveMover {
  uint32_t id = 0;
  MoverState state;
  Eigen::Vector3f half;
  float reflectivity = 0.f, azimuth = 0.f, half_width = 0.f;
  uint16_t label = 0;
};

class Traffic {
 public:
  Traffic() = default;
  Traffic(std::vector<std::vector<Eigen::Vector2f>> paths, std::vector<Mover> movers);

  size_t size() const { return movers_.size(); }
  const Mover& mover(size_t i) const { return movers_[i]; }
  MoverState state(size_t i, double t, const World& world) const;
  // Movers within `range` of the sensor at time t0, for rays fired within the next `sweep` seconds.
  std::vector<ActiveMover> active(const Eigen::Isometry3d& T_world_sensor, double t0, float range, float sweep,
                                  const World& world) const;

 private:
  std::vector<std::vector<Eigen::Vector2f>> paths_;
  std::vector<std::vector<float>> arcs_;
  std::vector<Mover> movers_;
};

// The mover's box at time t0 + dt against a ray; range along the unit direction d.
bool hit_mover(const ActiveMover& m, const Eigen::Vector3f& o, const Eigen::Vector3f& d, float dt, float& range,
               float& cos_incidence);

// Traffic of a street grid (streets on the grid lines of [lo, hi], in blocks), of a divided
// highway along `center`, and of hikers and cyclists on a trail.
Traffic make_city_traffic(uint64_t seed, float block, Eigen::Vector2i lo, Eigen::Vector2i hi);
Traffic make_highway_traffic(uint64_t seed, const std::vector<Eigen::Vector2f>& center);
Traffic make_trail_traffic(uint64_t seed, const std::vector<Eigen::Vector2f>& trail);

}  // namespace gcmap::sim
