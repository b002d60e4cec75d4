#include "gcmap/sim/scenario.hpp"

#include <algorithm>
#include <cmath>

#include "gcmap/core/error.hpp"

namespace gcmap::sim {

namespace {
using Waypoints = std::initializer_list<std::pair<float, float>>;

void add_waypoints(Scenario& s, Waypoints pts) {
  for (auto [x, y] : pts) s.waypoints.emplace_back(x, y);
}

// Routes 1, 2, ... of the scenarios that have them, in blocks on the grid of route 0. Each starts
// elsewhere and drives some of route 0's streets in the same direction (where ScanContext
// recognizes places) and some in the opposite one.
std::vector<Eigen::Vector2f> other_route(const std::string& name, int route, const std::vector<Eigen::Vector2f>& route0) {
  std::vector<Eigen::Vector2f> out;
  auto from = [&](Waypoints pts) {
    for (auto [x, y] : pts) out.emplace_back(x, y);
  };
  if (name == "loop") {
    // From the first loop's far corner, the rest of route 0, then back along its first street.
    out.assign(route0.begin() + 2, route0.end());
    out.emplace_back(0.f, 0.f);
  } else if (name == "small" && route == 1) {
    from({{0.5f, 0}, {1, 0}, {1, 1}, {0, 1}, {0, 0}, {0.75f, 0}});  // the same loop, from 20 m further
  } else if (name == "small") {
    from({{0.75f, 0}, {2, 0}, {2, 1}, {1, 1}, {1, 0}, {1.25f, 0}});  // the next block, from 30 m into route 0
  } else if (route == 1) {                                           // city
    from({{5, 1}, {3, 1}, {3, 3}, {1, 3}, {1, -1}, {4, -1}, {4, 2}});
  } else {
    from({{-1, 5}, {4, 5}, {4, 2}, {0, 2}, {0, 0}, {-1, 0}});
  }
  return out;
}

}  // namespace

int num_routes(const std::string& name) {
  if (name == "loop") return 2;
  if (name == "small" || name == "city") return 3;
  return 1;
}

Scenario make_scenario(const std::string& name, int frames, int route) {
  Scenario s;
  s.name = name;
  if (name == "loop") {
    // A 600 m loop back to the start, then a long detour that comes back to a corner of the first
    // loop and drives one of its streets in the opposite direction: about 1.55 km.
    add_waypoints(s, {{0, 0}, {3, 0}, {3, 3}, {0, 3}, {0, 0}, {0, -2}, {5, -2}, {5, 4}, {3, 4}, {3, 3}, {3, 0}});
    s.frames = 1500;
    s.description = "1.55 km through a street grid: a 600 m loop, a 800 m detour, an opposite-direction revisit";
  } else if (name == "small") {
    s.block = 40.f;
    add_waypoints(s, {{0, 0}, {1, 0}, {1, 1}, {0, 1}, {0, 0}, {0.25f, 0}});
    s.frames = 150;
    s.description = "one 160 m block loop with a revisit of the start";
  } else if (name == "corridor") {
    add_waypoints(s, {{0, 0}, {10, 0}});
    s.frames = 500;
    s.feature_poor = true;
    s.description = "a 500 m straight street between flat facades: degenerate along the street";
  } else if (name == "tunnel") {
    // Streets, then a 300 m canyon of flat walls entered while accelerating from rest, then streets:
    // in its middle both ends lie beyond the sensor's range (100 m).
    s.block = 40.f;
    add_waypoints(s, {{0, 0}, {10, 0}});
    s.tunnel_from = 1, s.tunnel_to = 9;
    s.realistic = true;
    s.cruise_min = 12.f, s.cruise_max = 16.f;
    s.description = "400 m from rest through a 300 m canyon of flat walls: degenerate along it while the speed changes";
  } else if (name == "city") {
    // 3.7 km over a 500 m x 500 m grid of 100 m blocks: a 1.2 km loop, then streets of it again in
    // the same direction (from 1.2 km and 3.4 km) and in the opposite one (from 2.6 km).
    s.block = 100.f;
    add_waypoints(
        s,
        {{0, 0}, {3, 0}, {3, 3}, {0, 3}, {0, 0}, {2, 0}, {2, 5}, {5, 5}, {5, 3}, {3, 3}, {3, 0}, {1, 0}, {1, 3}, {0, 3}, {0, 1}});
    s.realistic = true;
    s.cruise_min = 8.5f, s.cruise_max = 14.5f, s.stop_every = 2;
    s.terrain = Terrain{6.f, 120.f, 4.f, 90.f, kRoad, 0.1f, 160};
    s.description =
        "3.7 km, 10 Hz, through a 500 m x 500 m street grid with slopes, traffic and stops; "
        "revisits in both directions, one after 2.6 km";
  } else if (name == "highway") {
    s.scene = SceneKind::highway;
    s.block = 100.f;
    add_waypoints(s, {{0, 0}, {8, 0}, {14, 4}, {20, 4}});
    s.realistic = true;
    s.corner_radius = 250.f, s.lane_offset = 5.75f;
    s.cruise_min = 25.f, s.cruise_max = 30.f, s.rest_at_ends = false;
    s.terrain = Terrain{4.f, 400.f, 3.f, 300.f, kRoad, 0.1f, 160};
    s.description =
        "2.1 km of divided highway at 25-30 m/s: guardrails, sparse trees, few buildings, fast traffic "
        "(degenerate along the road)";
  } else if (name == "forest") {
    s.scene = SceneKind::forest;
    s.block = 30.f;
    add_waypoints(s, {{0, 0}, {4, 0.5f}, {7, -1}, {9, 1.5f}, {8.5f, 5}, {5, 6.5f}, {2, 5.5f}, {-1, 3.5f}, {0, 0}, {2, 0.25f}});
    s.realistic = true;
    s.corner_radius = 10.f, s.lane_offset = 0.f;
    s.cruise_min = 4.f, s.cruise_max = 7.f, s.lateral_accel = 1.5f;
    s.terrain = Terrain{3.f, 45.f, 2.5f, 35.f, kTerrain, 0.15f, 200};
    s.description =
        "a 0.9 km hilly forest trail loop with hikers and cyclists: trees, bushes, rocks, "
        "partial returns through canopies";
  } else if (name == "handheld") {
    // A person walking the inner sidewalk of a block loop (all left turns, down to 0.7 m radius),
    // waiting at every second crossing, with a handheld sensor that bounces, sways and glances
    // aside; sloped streets.
    s.block = 40.f;
    add_waypoints(s, {{0, 0}, {1, 0}, {1, 1}, {0, 1}, {0, 0}, {0.5f, 0}});
    s.realistic = true;
    s.corner_radius = 13.f, s.lane_offset = -8.5f;  // the inner curve: 0.7 m at its tightest
    s.cruise_min = 1.0f, s.cruise_max = 1.5f, s.lateral_accel = 3.f, s.stop_every = 2;
    s.sensor_height = 1.5f, s.handheld = true;
    s.terrain = Terrain{3.f, 60.f, 2.f, 45.f, kRoad, 0.1f, 160};
    s.description =
        "a 120 m walk around a block on its sidewalk, 1-1.5 m/s with waits at crossings, the sensor in hand: gait "
        "bounce and sway, glances aside at up to 190 deg/s, tight corners, sloped streets";
  } else {
    throw Error("--scenario: expected loop, small, corridor, tunnel, city, highway, forest or handheld, got '" + name + "'");
  }
  if (route < 0 || route >= num_routes(name))
    throw Error("--route: the '" + name + "' scenario has routes 0 to " + std::to_string(num_routes(name) - 1) + ", got " +
                std::to_string(route));
  s.world_waypoints = s.waypoints;
  if (route > 0) s.waypoints = other_route(name, route, s.waypoints);
  if (frames < 0) throw Error("--frames: must be >= 0");
  if (frames > 0) s.frames = frames;
  if (frames == 1 || (!s.realistic && s.frames < 2)) throw Error("--frames: need at least 2 frames");
  return s;
}

std::vector<Eigen::Vector2f> route_centerline(const Scenario& s, std::vector<size_t>* corner_starts) {
  std::vector<Eigen::Vector2f> pts;
  // A corner's first point repeats the straight's last: a repeated vertex has no tangent of its own,
  // and shifted sideways along a turned one it steps back (a walker's 1 cm jolt, 190 m/s^2 to an IMU).
  const auto push = [&pts](const Eigen::Vector2f& p) {
    if (pts.empty() || (p - pts.back()).norm() > 1e-3f) pts.push_back(p);
  };
  const float radius = s.corner_radius, step = 0.05f;
  const size_t n = s.waypoints.size();
  if (corner_starts) corner_starts->assign(n, 0);
  for (size_t k = 0; k + 1 < n; ++k) {
    const Eigen::Vector2f a = s.waypoints[k] * s.block, b = s.waypoints[k + 1] * s.block;
    const Eigen::Vector2f d = (b - a).normalized();
    const float len = (b - a).norm();
    const float cut_in = (k > 0) ? radius : 0.f;
    const float cut_out = (k + 2 < n) ? radius : 0.f;
    for (float t = cut_in; t <= len - cut_out; t += step) push(a + t * d);
    if (corner_starts) (*corner_starts)[k + 1] = pts.size();
    if (k + 2 < n) {
      // Quadratic Bezier through the corner.
      const Eigen::Vector2f c = b, p0 = b - radius * d;
      const Eigen::Vector2f d2 = (s.waypoints[k + 2] * s.block - b).normalized();
      const Eigen::Vector2f p2 = b + radius * d2;
      for (float t = 0.f; t < 1.f; t += step / (1.6f * radius)) {
        push((1 - t) * (1 - t) * p0 + 2 * (1 - t) * t * c + t * t * p2);
      }
    }
  }
  return pts;
}

std::vector<Eigen::Vector2f> shifted_right(const std::vector<Eigen::Vector2f>& pts, float offset) {
  std::vector<Eigen::Vector2f> out(pts.size());
  for (size_t i = 0; i < pts.size(); ++i) {
    const Eigen::Vector2f t = (pts[std::min(i + 1, pts.size() - 1)] - pts[i > 0 ? i - 1 : 0]).normalized();
    out[i] = pts[i] + offset * Eigen::Vector2f(t.y(), -t.x());
  }
  return out;
}

}  // namespace gcmap::sim
