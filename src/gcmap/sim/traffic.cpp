#include "gcmap/sim/traffic.hpp"

#include <algorithm>
#include <cmath>

#include "gcmap/sim/rng.hpp"

namespace gcmap::sim {

namespace {

constexpr float kPi = 3.14159265f;

Mover make_mover(Rng& r, uint32_t path, float length, uint16_t label) {
  Mover m;
  m.path = path;
  m.s0 = r.uniform(0.f, length);
  m.label = label;
  m.reflectivity = r.uniform(0.1f, 0.8f);
  if (label == kMovingCar) {
    m.speed = r.uniform(6.f, 13.f);
    m.half = Eigen::Vector3f(r.uniform(2.0f, 2.4f), r.uniform(0.85f, 1.0f), r.uniform(0.7f, 0.85f));
  } else if (label == kMovingBicyclist) {
    m.speed = r.uniform(3.5f, 6.5f);
    m.half = Eigen::Vector3f(0.9f, 0.3f, 0.85f);
  } else {  // pedestrian
    m.speed = r.uniform(0.9f, 1.7f);
    m.half = Eigen::Vector3f(0.25f, 0.3f, r.uniform(0.8f, 0.95f));
  }
  return m;
}

float path_length(const std::vector<Eigen::Vector2f>& p) {
  float l = 0.f;
  for (size_t i = 1; i < p.size(); ++i) l += (p[i] - p[i - 1]).norm();
  return l;
}

}  // namespace

Traffic::Traffic(std::vector<std::vector<Eigen::Vector2f>> paths, std::vector<Mover> movers)
    : paths_(std::move(paths)), movers_(std::move(movers)) {
  for (const auto& p : paths_) {
    std::vector<float> arc(p.size(), 0.f);
    for (size_t i = 1; i < p.size(); ++i) arc[i] = arc[i - 1] + (p[i] - p[i - 1]).norm();
    arcs_.push_back(std::move(arc));
  }
}

MoverState Traffic::state(size_t i, double t, const World& world) const {
  const Mover& m = movers_[i];
  const auto& p = paths_[m.path];
  const auto& arc = arcs_[m.path];
  const double len = arc.back();
  const float s = static_cast<float>(std::fmod(m.s0 + m.speed * t, len) + (m.s0 + m.speed * t < 0 ? len : 0.0));
  const size_t j = std::clamp<size_t>(std::upper_bound(arc.begin(), arc.end(), s) - arc.begin(), 1, p.size() - 1);
  const Eigen::Vector2f dir = (p[j] - p[j - 1]).normalized();
  const float f = (s - arc[j - 1]) / std::max(arc[j] - arc[j - 1], 1e-6f);
  const Eigen::Vector2f q = p[j - 1] + f * (p[j] - p[j - 1]) + m.offset * Eigen::Vector2f(dir.y(), -dir.x());
  MoverState st;
  st.center = Eigen::Vector3f(q.x(), q.y(), world.ground_height(q.x(), q.y()) + m.half.z());
  st.velocity = Eigen::Vector3f(dir.x(), dir.y(), world.ground_gradient(q.x(), q.y()).dot(dir)) * m.speed;
  st.yaw = std::atan2(dir.y(), dir.x());
  return st;
}

std::vector<ActiveMover> Traffic::active(const Eigen::Isometry3d& T_world_sensor, double t0, float range, float sweep,
                                         const World& world) const {
  std::vector<ActiveMover> out;
  const Eigen::Isometry3f T_sensor_world = T_world_sensor.inverse().cast<float>();
  for (size_t i = 0; i < movers_.size(); ++i) {
    const MoverState st = state(i, t0, world);
    const Eigen::Vector3f local = T_sensor_world * st.center;
    const float dist = local.head<2>().norm(), radius = movers_[i].half.head<2>().norm() + movers_[i].speed * sweep;
    if (dist > range + radius) continue;
    ActiveMover a;
    a.id = static_cast<uint32_t>(i);
    a.state = st;
    a.half = movers_[i].half;
    a.reflectivity = movers_[i].reflectivity;
    a.label = movers_[i].label;
    a.azimuth = std::atan2(local.y(), local.x());
    // Margin for the sensor's own motion (a few metres, a few degrees of turn) during the sweep.
    const float r = radius + 4.f;
    a.half_width = dist > r ? std::asin(r / dist) + 0.1f : kPi;
    out.push_back(a);
  }
  return out;
}

bool hit_mover(const ActiveMover& m, const Eigen::Vector3f& o, const Eigen::Vector3f& d, float dt, float& range,
               float& cos_incidence) {
  const float c = std::cos(m.state.yaw), s = std::sin(m.state.yaw);
  const Eigen::Vector3f q = o - (m.state.center + dt * m.state.velocity);
  const Eigen::Vector3f ol(c * q.x() + s * q.y(), -s * q.x() + c * q.y(), q.z());
  const Eigen::Vector3f dl(c * d.x() + s * d.y(), -s * d.x() + c * d.y(), d.z());
  int axis = 0;
  if (!intersect_box(-m.half, m.half, ol, Eigen::Vector3f(1.f / dl.x(), 1.f / dl.y(), 1.f / dl.z()), range, axis)) return false;
  cos_incidence = std::abs(dl[axis]);
  return true;
}

Traffic make_city_traffic(uint64_t seed, float block, Eigen::Vector2i lo, Eigen::Vector2i hi) {
  Rng r(hash_key(seed, 0x7A));
  std::vector<std::vector<Eigen::Vector2f>> paths;
  std::vector<Mover> movers;
  const float a = (lo.x() - 1) * block, b = (hi.x() + 1) * block, c = (lo.y() - 1) * block, e = (hi.y() + 1) * block;
  auto add_street = [&](Eigen::Vector2f p, Eigen::Vector2f q) {
    for (int dir = 0; dir < 2; ++dir) {
      const uint32_t id = static_cast<uint32_t>(paths.size());
      paths.push_back(dir == 0 ? std::vector<Eigen::Vector2f>{p, q} : std::vector<Eigen::Vector2f>{q, p});
      const float len = (q - p).norm();
      for (int k = 0; k < 4; ++k) movers.push_back(make_mover(r, id, len, kMovingCar)), movers.back().offset = 2.f;
      movers.push_back(make_mover(r, id, len, kMovingBicyclist)), movers.back().offset = 3.9f;
      for (int k = 0; k < 6; ++k)
        movers.push_back(make_mover(r, id, len, kMovingPerson)), movers.back().offset = r.uniform(7.8f, 9.2f);
    }
  };
  for (int k = lo.x() - 1; k <= hi.x() + 1; ++k) add_street({k * block, c}, {k * block, e});
  for (int k = lo.y() - 1; k <= hi.y() + 1; ++k) add_street({a, k * block}, {b, k * block});
  return Traffic(std::move(paths), std::move(movers));
}

Traffic make_highway_traffic(uint64_t seed, const std::vector<Eigen::Vector2f>& center) {
  Rng r(hash_key(seed, 0x7B));
  std::vector<std::vector<Eigen::Vector2f>> paths{center, std::vector<Eigen::Vector2f>(center.rbegin(), center.rend())};
  const float len = path_length(center);
  std::vector<Mover> movers;
  for (uint32_t dir = 0; dir < 2; ++dir) {
    for (int k = 0; k < 45; ++k) {
      Mover m = make_mover(r, dir, len, kMovingCar);
      m.speed = r.uniform(22.f, 34.f);
      m.offset = 2.25f + 3.5f * static_cast<float>(k % 3);
      if (k % 7 == 0) m.label = kMovingTruck, m.half = Eigen::Vector3f(6.f, 1.25f, 1.9f), m.speed = r.uniform(20.f, 25.f);
      movers.push_back(m);
    }
  }
  return Traffic(std::move(paths), std::move(movers));
}

Traffic make_trail_traffic(uint64_t seed, const std::vector<Eigen::Vector2f>& trail) {
  Rng r(hash_key(seed, 0x7C));
  std::vector<std::vector<Eigen::Vector2f>> paths{trail, std::vector<Eigen::Vector2f>(trail.rbegin(), trail.rend())};
  const float len = path_length(trail);
  std::vector<Mover> movers;
  for (uint32_t dir = 0; dir < 2; ++dir) {
    for (int k = 0; k < 12; ++k) movers.push_back(make_mover(r, dir, len, kMovingPerson)), movers.back().offset = 1.8f;
    for (int k = 0; k < 4; ++k) movers.push_back(make_mover(r, dir, len, kMovingBicyclist)), movers.back().offset = 1.8f;
  }
  return Traffic(std::move(paths), std::move(movers));
}

}  // namespace gcmap::sim
