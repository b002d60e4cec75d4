#include <algorithm>
#include <cmath>
#include <random>

#include "gcmap/sim/builders.hpp"
#include "gcmap/sim/rng.hpp"

namespace gcmap::sim {

namespace {

constexpr float kStreetHalf = 7.f, kSidewalkWidth = 3.f;
using Uniform = std::uniform_real_distribution<float>;

struct BlockContext {
  World& world;
  std::mt19937_64& rng;
  Uniform& u;
  float x0, x1, y0, y1;
  // A box on the ground (3 m deep) of the given height above the ground at its centre.
  void ground_box(float a0, float b0, float a1, float b1, float height, float refl, uint16_t label) const {
    const float g = world.ground_height(0.5f * (a0 + a1), 0.5f * (b0 + b1));
    world.add_box({Eigen::Vector3f(a0, b0, g - 3.f), Eigen::Vector3f(a1, b1, g + height), refl, label});
  }
};

void add_buildings(const BlockContext& k) {
  auto& rng = k.rng;
  auto& u = k.u;
  const float x0 = k.x0, x1 = k.x1, y0 = k.y0, y1 = k.y1;
  auto ground_box = [&](float a0, float b0, float a1, float b1, float h, float refl, uint16_t label) {
    k.ground_box(a0, b0, a1, b1, h, refl, label);
  };
  // Buildings along each side with varied facade depth, width and height, gaps between them.
  for (int side = 0; side < 4; ++side) {
    const bool along_x = side < 2;
    const float len = along_x ? x1 - x0 : y1 - y0;
    float s = u(rng) * 3.f;
    while (s < len - 4.f) {
      const float w = std::min(6.f + 14.f * u(rng), len - s);
      const float setback = 3.f * u(rng), depth = 8.f + 6.f * u(rng), h = 5.f + 20.f * u(rng);
      float a0, a1, b0, b1;
      if (along_x) {
        a0 = x0 + s, a1 = x0 + s + w;
        if (side == 0) b0 = y0 + setback, b1 = y0 + setback + depth;
        else b1 = y1 - setback, b0 = y1 - setback - depth;
        ground_box(a0, b0, a1, b1, h, 0.2f + 0.3f * u(rng), kBuilding);
      } else {
        b0 = y0 + s, b1 = y0 + s + w;
        if (side == 2) a0 = x0 + setback, a1 = x0 + setback + depth;
        else a1 = x1 - setback, a0 = x1 - setback - depth;
        ground_box(a0, b0, a1, b1, h, 0.2f + 0.3f * u(rng), kBuilding);
      }
      s += w + (u(rng) < 0.4f ? 2.f + 6.f * u(rng) : 0.3f);
    }
  }
}

void add_street_furniture(const BlockContext& ctx) {
  auto& rng = ctx.rng;
  auto& u = ctx.u;
  World& world = ctx.world;
  const float x0 = ctx.x0, x1 = ctx.x1, y0 = ctx.y0, y1 = ctx.y1;
  const float sidewalk = kSidewalkWidth;
  // Street furniture along the block's four curbs.
  const float curb[4] = {y0 - sidewalk + 0.5f, y1 + sidewalk - 0.5f, x0 - sidewalk + 0.5f, x1 + sidewalk - 0.5f};
  for (int side = 0; side < 4; ++side) {
    const bool along_x = side < 2;
    const float a_lo = along_x ? x0 : y0, a_hi = along_x ? x1 : y1;
    for (float a = a_lo + 2.f + 8.f * u(rng); a < a_hi - 2.f; a += 6.f + 14.f * u(rng)) {
      const float c = curb[side];
      const Eigen::Vector2f p = along_x ? Eigen::Vector2f(a, c) : Eigen::Vector2f(c, a);
      const float g = world.ground_height(p.x(), p.y());
      const float kind = u(rng);
      if (kind < 0.35f) {  // pole
        world.add_cylinder({p, 0.12f + 0.08f * u(rng), g - 1.f, g + 4.f + 4.f * u(rng), 0.6f, kPole});
      } else if (kind < 0.7f) {  // tree: trunk and a cluttered canopy of spheres
        const float trunk = 2.f + 1.5f * u(rng);
        world.add_cylinder({p, 0.18f + 0.1f * u(rng), g - 1.f, g + trunk, 0.25f, kTrunk});
        const int blobs = 4 + static_cast<int>(4 * u(rng));
        for (int k = 0; k < blobs; ++k) {
          const Eigen::Vector3f off(2.f * u(rng) - 1.f, 2.f * u(rng) - 1.f, 1.2f * u(rng));
          world.add_sphere(
              {Eigen::Vector3f(p.x(), p.y(), g + trunk + 1.f) + 1.3f * off, 0.7f + 0.9f * u(rng), 0.15f, kVegetation});
        }
      } else {  // parked car on the street side of the curb
        const float off = along_x ? (side == 0 ? -2.2f : 2.2f) : (side == 2 ? -2.2f : 2.2f);
        const Eigen::Vector2f q = along_x ? Eigen::Vector2f(p.x(), p.y() + off) : Eigen::Vector2f(p.x() + off, p.y());
        const Eigen::Vector2f half = along_x ? Eigen::Vector2f(2.2f, 0.9f) : Eigen::Vector2f(0.9f, 2.2f);
        const float gq = world.ground_height(q.x(), q.y());
        world.add_box({Eigen::Vector3f(q.x() - half.x(), q.y() - half.y(), gq - 0.5f),
                       Eigen::Vector3f(q.x() + half.x(), q.y() + half.y(), gq + 1.4f + 0.3f * u(rng)), 0.8f, kCar});
      }
    }
  }
}

}  // namespace

void build_city_blocks(World& world, uint64_t seed, float block, Eigen::Vector2i lo, Eigen::Vector2i hi, bool feature_poor,
                       Eigen::Vector2i tunnel) {
  std::mt19937_64 rng(seed);
  Uniform u(0.f, 1.f);
  const float street_half = kStreetHalf, sidewalk = kSidewalkWidth;
  for (int bx = lo.x() - 1; bx <= hi.x(); ++bx) {
    for (int by = lo.y() - 1; by <= hi.y(); ++by) {
      // Block interior between the streets on x = bx*block and x = (bx+1)*block.
      const float x0 = bx * block + street_half + sidewalk, x1 = (bx + 1) * block - street_half - sidewalk;
      const float y0 = by * block + street_half + sidewalk, y1 = (by + 1) * block - street_half - sidewalk;
      if (x1 - x0 < 6.f || y1 - y0 < 6.f) continue;
      const BlockContext k{world, rng, u, x0, x1, y0, y1};
      if (bx >= tunnel.x() && bx < tunnel.y()) {
        const float gap = 2.f * (street_half + sidewalk);  // joins the next wall of the tunnel
        k.ground_box(x0, y0, bx + 1 < tunnel.y() ? x1 + gap : x1, y1, 12.f, 0.3f, kBuilding);
        continue;
      }
      if (feature_poor) {
        // One long flat facade per block side: a degenerate corridor.
        k.ground_box(x0, y0, x1, y1, 12.f, 0.3f, kBuilding);
        continue;
      }
      add_buildings(k);
      add_street_furniture(k);
      // Occasional garden wall inside the block.
      if (u(rng) < 0.3f) {
        const float xm = x0 + (x1 - x0) * (0.3f + 0.4f * u(rng));
        k.ground_box(xm, y0 + 2.f, xm + 0.3f, y1 - 2.f, 2.f, 0.4f, kFence);
      }
    }
  }
}

void add_sidewalks(World& world, float block, Eigen::Vector2i lo, Eigen::Vector2i hi) {
  const float inner = kStreetHalf + kSidewalkWidth, piece = 4.f;
  auto strip = [&](float a0, float b0, float a1, float b1) {  // split so each piece follows the slope
    const bool along_x = a1 - a0 > b1 - b0;
    const float len = along_x ? a1 - a0 : b1 - b0;
    const int n = std::max(1, static_cast<int>(std::ceil(len / piece)));
    for (int i = 0; i < n; ++i) {
      const float s0 = len * i / n, s1 = len * (i + 1) / n;
      const Eigen::Vector2f p0 = along_x ? Eigen::Vector2f(a0 + s0, b0) : Eigen::Vector2f(a0, b0 + s0);
      const Eigen::Vector2f p1 = along_x ? Eigen::Vector2f(a0 + s1, b1) : Eigen::Vector2f(a1, b0 + s1);
      const Eigen::Vector2f c = 0.5f * (p0 + p1);
      const float g = world.ground_height(c.x(), c.y());
      world.add_box({Eigen::Vector3f(p0.x(), p0.y(), g - 0.5f), Eigen::Vector3f(p1.x(), p1.y(), g + 0.15f), 0.2f, kSidewalk});
    }
  };
  for (int bx = lo.x() - 1; bx <= hi.x(); ++bx) {
    for (int by = lo.y() - 1; by <= hi.y(); ++by) {
      const float x0 = bx * block + inner, x1 = (bx + 1) * block - inner;
      const float y0 = by * block + inner, y1 = (by + 1) * block - inner;
      if (x1 - x0 < 6.f || y1 - y0 < 6.f) continue;
      strip(x0 - kSidewalkWidth, y0 - kSidewalkWidth, x1 + kSidewalkWidth, y0);
      strip(x0 - kSidewalkWidth, y1, x1 + kSidewalkWidth, y1 + kSidewalkWidth);
      strip(x0 - kSidewalkWidth, y0, x0, y1);
      strip(x1, y0, x1 + kSidewalkWidth, y1);
    }
  }
}

void add_parked_car_dynamics(World& world, uint64_t seed, float duration) {
  std::vector<Box>& boxes = world.boxes();
  for (size_t i = 0; i < boxes.size(); ++i) {
    if (boxes[i].label != kCar) continue;
    Rng r(hash_key(seed, 0xCA5, i));
    const float fate = r.uniform(), when = r.uniform(0.15f, 0.85f) * duration;
    if (fate < 0.3f) boxes[i].t_end = when;         // leaves: gone on a later revisit
    else if (fate < 0.4f) boxes[i].t_begin = when;  // arrives
    boxes[i].reflectivity = r.uniform() < 0.3f ? r.uniform(0.03f, 0.08f) : r.uniform(0.3f, 0.9f);
  }
}

void set_porous_vegetation(World& world, uint64_t seed, bool on) {
  std::vector<Sphere>& spheres = world.spheres();
  for (size_t i = 0; i < spheres.size(); ++i) {
    Sphere& s = spheres[i];
    if (s.label != kVegetation) continue;
    if (!on) s.porosity = 0.f;
    else if (s.porosity == 0.f) s.porosity = Rng(hash_key(seed, 0x7EE, i)).uniform(0.25f, 0.5f);
  }
}

}  // namespace gcmap::sim
