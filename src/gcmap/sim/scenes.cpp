#include <algorithm>
#include <cmath>

#include "gcmap/sim/builders.hpp"
#include "gcmap/sim/rng.hpp"

namespace gcmap::sim {

namespace {

// Samples of a dense polyline every `step` metres: position and unit tangent.
struct Station {
  Eigen::Vector2f p, t;
};
std::vector<Station> stations(const std::vector<Eigen::Vector2f>& line, float step) {
  std::vector<Station> out;
  float next = 0.f, s = 0.f;
  for (size_t i = 1; i < line.size(); ++i) {
    const float d = (line[i] - line[i - 1]).norm();
    if (d <= 0.f) continue;
    while (next <= s + d) {
      const Eigen::Vector2f t = (line[i] - line[i - 1]) / d;
      out.push_back({line[i - 1] + (next - s) * t, t});
      next += step;
    }
    s += d;
  }
  return out;
}

Eigen::Vector2f left_of(const Station& st, float offset) { return st.p + offset * Eigen::Vector2f(-st.t.y(), st.t.x()); }

void add_tree(World& w, Rng& r, Eigen::Vector2f p, float height, float porosity_lo, float porosity_hi) {
  const float g = w.ground_height(p.x(), p.y());
  const float trunk_r = r.uniform(0.15f, 0.4f), base = height * r.uniform(0.35f, 0.6f);
  w.add_cylinder({p, trunk_r, g - 1.f, g + base + 1.f, 0.3f, kTrunk});
  const int blobs = 3 + static_cast<int>(4 * r.uniform());
  const float spread = 0.25f * height;
  for (int k = 0; k < blobs; ++k) {
    const Eigen::Vector3f c(p.x() + r.uniform(-1.f, 1.f) * spread, p.y() + r.uniform(-1.f, 1.f) * spread,
                            g + base + r.uniform(0.5f, 1.f) * (height - base) * 0.7f);
    Sphere s{c, r.uniform(0.2f, 0.35f) * height, 0.2f, kVegetation};
    s.porosity = r.uniform(porosity_lo, porosity_hi);
    w.add_sphere(s);
  }
}

}  // namespace

void build_highway(World& world, uint64_t seed, const std::vector<Eigen::Vector2f>& center) {
  Rng r(hash_key(seed, 0x41));
  const float rail_step = 4.f;
  for (const Station& st : stations(center, rail_step)) {
    const float yaw = std::atan2(st.t.y(), st.t.x());
    for (float off : {-12.f, 12.f}) {  // guardrails: a rail on posts
      const Eigen::Vector2f q = left_of(st, off), post = left_of(st, off + (off > 0 ? 0.2f : -0.2f));
      const float g = world.ground_height(q.x(), q.y());
      world.add_oriented_box(
          {Eigen::Vector3f(q.x(), q.y(), g + 0.6f), Eigen::Vector3f(0.5f * rail_step + 0.05f, 0.05f, 0.17f), yaw, 0.5f, kFence});
      world.add_cylinder({post, 0.08f, g - 0.5f, g + 0.75f, 0.4f, kFence});
    }
    const float g0 = world.ground_height(st.p.x(), st.p.y());  // concrete median barrier
    world.add_oriented_box({Eigen::Vector3f(st.p.x(), st.p.y(), g0 + 0.2f), Eigen::Vector3f(0.5f * rail_step + 0.02f, 0.3f, 0.7f),
                            yaw, 0.35f, kFence});
  }
  for (const Station& st : stations(center, 100.f)) {  // lamp posts on the median
    const float g = world.ground_height(st.p.x(), st.p.y());
    world.add_cylinder({left_of(st, 0.f), 0.15f, g - 1.f, g + 10.f, 0.6f, kPole});
  }
  for (const Station& st : stations(center, 6.f)) {
    for (float side : {-1.f, 1.f}) {
      if (r.uniform() < 0.3f) add_tree(world, r, left_of(st, side * r.uniform(16.f, 50.f)), r.uniform(5.f, 12.f), 0.2f, 0.4f);
      if (r.uniform() < 0.01f) {  // an occasional building far from the road
        const Eigen::Vector2f q = left_of(st, side * r.uniform(35.f, 80.f));
        const float g = world.ground_height(q.x(), q.y()), h = r.uniform(4.f, 12.f);
        world.add_oriented_box({Eigen::Vector3f(q.x(), q.y(), g + 0.5f * h - 1.5f),
                                Eigen::Vector3f(r.uniform(5.f, 15.f), r.uniform(4.f, 10.f), 0.5f * h + 1.5f),
                                std::atan2(st.t.y(), st.t.x()) + r.uniform(-0.3f, 0.3f), r.uniform(0.2f, 0.5f), kBuilding});
      }
    }
  }
}

void build_forest(World& world, uint64_t seed, const std::vector<Eigen::Vector2f>& trail) {
  Rng r(hash_key(seed, 0xF0));
  // Distance to the trail on a 1 m grid around it, so nothing grows on the trail.
  const float margin = 60.f, clear = 3.f;
  Eigen::Vector2f lo = trail.front(), hi = lo;
  for (const auto& p : trail) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
  lo.array() -= margin, hi.array() += margin;
  const int nx = static_cast<int>(hi.x() - lo.x()) + 1, ny = static_cast<int>(hi.y() - lo.y()) + 1;
  std::vector<float> dist(static_cast<size_t>(nx) * ny, 1e9f);
  for (const Station& st : stations(trail, 1.f)) {
    const int cx = static_cast<int>(st.p.x() - lo.x()), cy = static_cast<int>(st.p.y() - lo.y()), rr = static_cast<int>(margin);
    for (int y = std::max(0, cy - rr); y <= std::min(ny - 1, cy + rr); ++y) {
      for (int x = std::max(0, cx - rr); x <= std::min(nx - 1, cx + rr); ++x) {
        float& d = dist[static_cast<size_t>(y) * nx + x];
        d = std::min(d, (Eigen::Vector2f(lo.x() + x + 0.5f, lo.y() + y + 0.5f) - st.p).norm());
      }
    }
  }
  auto distance = [&](Eigen::Vector2f p) {
    const int x = static_cast<int>(p.x() - lo.x()), y = static_cast<int>(p.y() - lo.y());
    return (x < 0 || y < 0 || x >= nx || y >= ny) ? 1e9f : dist[static_cast<size_t>(y) * nx + x];
  };
  const float cell = 4.5f;
  for (float y = lo.y(); y < hi.y(); y += cell) {
    for (float x = lo.x(); x < hi.x(); x += cell) {
      const Eigen::Vector2f p(x + r.uniform(0.f, cell), y + r.uniform(0.f, cell));
      const float d = distance(p), kind = r.uniform();
      if (d < clear || d > margin) continue;
      const float g = world.ground_height(p.x(), p.y());
      if (kind < 0.55f) {
        add_tree(world, r, p, r.uniform(7.f, 16.f), 0.3f, 0.6f);
      } else if (kind < 0.85f) {  // bush
        Sphere s{Eigen::Vector3f(p.x(), p.y(), g + 0.2f), r.uniform(0.5f, 1.2f), 0.2f, kVegetation};
        s.porosity = r.uniform(0.4f, 0.7f);
        world.add_sphere(s);
      } else if (kind < 0.95f) {  // rock
        world.add_sphere({Eigen::Vector3f(p.x(), p.y(), g - 0.2f), r.uniform(0.3f, 1.0f), 0.35f, kTerrain});
      } else {  // fallen log
        world.add_oriented_box({Eigen::Vector3f(p.x(), p.y(), g + 0.2f), Eigen::Vector3f(r.uniform(2.f, 5.f), 0.25f, 0.25f),
                                r.uniform(0.f, 3.14159f), 0.3f, kTrunk});
      }
    }
  }
}

}  // namespace gcmap::sim
