#include "gcmap/sim/world.hpp"

#include <algorithm>
#include <cmath>
#include <random>

namespace gcmap::sim {

namespace {
constexpr float kHillAmp1 = 1.6f, kHillLen1 = 110.f, kHillAmp2 = 1.1f, kHillLen2 = 75.f;
constexpr float kMaxGrad = kHillAmp1 / kHillLen1 + kHillAmp2 / kHillLen2 + 1e-3f;
}  // namespace

float World::ground_height(float x, float y) const {
  return kHillAmp1 * std::sin(x / kHillLen1) + kHillAmp2 * std::sin(y / kHillLen2 + 0.7f);
}

Eigen::Vector2f World::ground_gradient(float x, float y) const {
  return {kHillAmp1 / kHillLen1 * std::cos(x / kHillLen1), kHillAmp2 / kHillLen2 * std::cos(y / kHillLen2 + 0.7f)};
}

World::World(uint64_t seed, float block, Eigen::Vector2i lo, Eigen::Vector2i hi, bool feature_poor) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<float> u(0.f, 1.f);
  const float street_half = 7.f, sidewalk = 3.f;
  origin_ = Eigen::Vector2f(lo.x() * block - block, lo.y() * block - block);
  nx_ = static_cast<int>(std::ceil(((hi.x() - lo.x()) + 2) * block / cell_));
  ny_ = static_cast<int>(std::ceil(((hi.y() - lo.y()) + 2) * block / cell_));
  build_cells_.assign(static_cast<size_t>(nx_) * ny_, {});

  auto ground_box = [&](float x0, float y0, float x1, float y1, float height, float refl) {
    const float g = ground_height(0.5f * (x0 + x1), 0.5f * (y0 + y1));
    add_box({Eigen::Vector3f(x0, y0, g - 3.f), Eigen::Vector3f(x1, y1, g + height), refl});
  };
  for (int bx = lo.x() - 1; bx <= hi.x(); ++bx) {
    for (int by = lo.y() - 1; by <= hi.y(); ++by) {
      // Block interior between the streets on x = bx*block and x = (bx+1)*block.
      const float x0 = bx * block + street_half + sidewalk, x1 = (bx + 1) * block - street_half - sidewalk;
      const float y0 = by * block + street_half + sidewalk, y1 = (by + 1) * block - street_half - sidewalk;
      if (x1 - x0 < 6.f || y1 - y0 < 6.f) continue;
      if (feature_poor) {
        // One long flat facade per block side: a degenerate corridor.
        ground_box(x0, y0, x1, y1, 12.f, 0.3f);
        continue;
      }
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
            ground_box(a0, b0, a1, b1, h, 0.2f + 0.3f * u(rng));
          } else {
            b0 = y0 + s, b1 = y0 + s + w;
            if (side == 2) a0 = x0 + setback, a1 = x0 + setback + depth;
            else a1 = x1 - setback, a0 = x1 - setback - depth;
            ground_box(a0, b0, a1, b1, h, 0.2f + 0.3f * u(rng));
          }
          s += w + (u(rng) < 0.4f ? 2.f + 6.f * u(rng) : 0.3f);
        }
      }
      // Street furniture along the block's four curbs.
      const float curb[4] = {y0 - sidewalk + 0.5f, y1 + sidewalk - 0.5f, x0 - sidewalk + 0.5f, x1 + sidewalk - 0.5f};
      for (int side = 0; side < 4; ++side) {
        const bool along_x = side < 2;
        const float a_lo = along_x ? x0 : y0, a_hi = along_x ? x1 : y1;
        for (float a = a_lo + 2.f + 8.f * u(rng); a < a_hi - 2.f; a += 6.f + 14.f * u(rng)) {
          const float c = curb[side];
          const Eigen::Vector2f p = along_x ? Eigen::Vector2f(a, c) : Eigen::Vector2f(c, a);
          const float g = ground_height(p.x(), p.y());
          const float kind = u(rng);
          if (kind < 0.35f) {  // pole
            add_cylinder({p, 0.12f + 0.08f * u(rng), g - 1.f, g + 4.f + 4.f * u(rng), 0.6f});
          } else if (kind < 0.7f) {  // tree: trunk and a cluttered canopy of spheres
            const float trunk = 2.f + 1.5f * u(rng);
            add_cylinder({p, 0.18f + 0.1f * u(rng), g - 1.f, g + trunk, 0.25f});
            const int blobs = 4 + static_cast<int>(4 * u(rng));
            for (int k = 0; k < blobs; ++k) {
              const Eigen::Vector3f off(2.f * u(rng) - 1.f, 2.f * u(rng) - 1.f, 1.2f * u(rng));
              add_sphere({Eigen::Vector3f(p.x(), p.y(), g + trunk + 1.f) + 1.3f * off, 0.7f + 0.9f * u(rng), 0.15f});
            }
          } else {  // parked car on the street side of the curb
            const float off = along_x ? (side == 0 ? -2.2f : 2.2f) : (side == 2 ? -2.2f : 2.2f);
            const Eigen::Vector2f q = along_x ? Eigen::Vector2f(p.x(), p.y() + off) : Eigen::Vector2f(p.x() + off, p.y());
            const Eigen::Vector2f half = along_x ? Eigen::Vector2f(2.2f, 0.9f) : Eigen::Vector2f(0.9f, 2.2f);
            const float gq = ground_height(q.x(), q.y());
            add_box({Eigen::Vector3f(q.x() - half.x(), q.y() - half.y(), gq - 0.5f),
                     Eigen::Vector3f(q.x() + half.x(), q.y() + half.y(), gq + 1.4f + 0.3f * u(rng)), 0.8f});
          }
        }
      }
      // Occasional garden wall inside the block.
      if (u(rng) < 0.3f) {
        const float xm = x0 + (x1 - x0) * (0.3f + 0.4f * u(rng));
        ground_box(xm, y0 + 2.f, xm + 0.3f, y1 - 2.f, 2.f, 0.4f);
      }
    }
  }
  // Compact the grid into CSR.
  cell_start_.assign(build_cells_.size() + 1, 0);
  for (size_t c = 0; c < build_cells_.size(); ++c) cell_start_[c + 1] = cell_start_[c] + build_cells_[c].size();
  cell_items_.reserve(cell_start_.back());
  for (auto& c : build_cells_) cell_items_.insert(cell_items_.end(), c.begin(), c.end());
  build_cells_.clear();
  build_cells_.shrink_to_fit();
}

void World::index(int kind, int id, Eigen::Vector2f lo, Eigen::Vector2f hi) {
  const int cx0 = std::max(0, static_cast<int>((lo.x() - origin_.x()) / cell_));
  const int cy0 = std::max(0, static_cast<int>((lo.y() - origin_.y()) / cell_));
  const int cx1 = std::min(nx_ - 1, static_cast<int>((hi.x() - origin_.x()) / cell_));
  const int cy1 = std::min(ny_ - 1, static_cast<int>((hi.y() - origin_.y()) / cell_));
  for (int x = cx0; x <= cx1; ++x)
    for (int y = cy0; y <= cy1; ++y) build_cells_[static_cast<size_t>(y) * nx_ + x].push_back((uint32_t(kind) << 28) | uint32_t(id));
}

void World::add_box(const Box& b) {
  index(0, static_cast<int>(boxes_.size()), b.min.head<2>(), b.max.head<2>());
  boxes_.push_back(b);
}
void World::add_cylinder(const Cylinder& c) {
  index(1, static_cast<int>(cylinders_.size()), c.center.array() - c.radius, c.center.array() + c.radius);
  cylinders_.push_back(c);
}
void World::add_sphere(const Sphere& s) {
  index(2, static_cast<int>(spheres_.size()), s.center.head<2>().array() - s.radius, s.center.head<2>().array() + s.radius);
  spheres_.push_back(s);
}

bool World::ground_hit(const Eigen::Vector3f& o, const Eigen::Vector3f& d, float t_max, float& t) const {
  // Sphere tracing on h(t) = z(t) - g(x(t), y(t)): |dh/dt| <= L, so a step of h/L never overshoots.
  const float L = std::abs(d.z()) + kMaxGrad * d.head<2>().norm();
  t = 0.f;
  for (int it = 0; it < 64 && t < t_max; ++it) {
    const Eigen::Vector3f p = o + t * d;
    const float h = p.z() - ground_height(p.x(), p.y());
    if (h < 2e-3f) return true;
    t += std::max(h / L, 1e-3f);
  }
  return false;
}

namespace {
inline bool hit_box(const Box& b, const Eigen::Vector3f& o, const Eigen::Vector3f& inv, float& t) {
  float t0 = 0.f, t1 = 1e30f;
  for (int k = 0; k < 3; ++k) {
    float a = (b.min[k] - o[k]) * inv[k], c = (b.max[k] - o[k]) * inv[k];
    if (a > c) std::swap(a, c);
    t0 = std::max(t0, a);
    t1 = std::min(t1, c);
    if (t0 > t1) return false;
  }
  if (t0 <= 0.f) return false;  // origin inside: ignore
  t = t0;
  return true;
}
inline bool hit_sphere(const Sphere& s, const Eigen::Vector3f& o, const Eigen::Vector3f& d, float& t) {
  const Eigen::Vector3f m = o - s.center;
  const float b = m.dot(d), c = m.squaredNorm() - s.radius * s.radius;
  const float disc = b * b - c;
  if (disc < 0.f) return false;
  t = -b - std::sqrt(disc);
  return t > 0.f;
}
inline bool hit_cylinder(const Cylinder& cy, const Eigen::Vector3f& o, const Eigen::Vector3f& d, float& t) {
  const Eigen::Vector2f m = o.head<2>() - cy.center;
  const Eigen::Vector2f dd = d.head<2>();
  const float a = dd.squaredNorm();
  if (a < 1e-12f) return false;
  const float b = m.dot(dd), c = m.squaredNorm() - cy.radius * cy.radius;
  const float disc = b * b - a * c;
  if (disc < 0.f) return false;
  t = (-b - std::sqrt(disc)) / a;
  if (t <= 0.f) return false;
  const float z = o.z() + t * d.z();
  return z >= cy.z0 && z <= cy.z1;
}
}  // namespace

bool World::raycast(const Eigen::Vector3f& o, const Eigen::Vector3f& d, float max_range, Hit& hit) const {
  float t_best = max_range;
  float refl = 0.f;
  bool found = false;
  float tg;
  if (ground_hit(o, d, max_range, tg) && tg < t_best) {
    t_best = tg;
    refl = 0.1f;
    found = true;
  }
  const Eigen::Vector3f inv(1.f / d.x(), 1.f / d.y(), 1.f / d.z());
  // 2D DDA over the grid cells along the ray's ground projection.
  const Eigen::Vector2f p = (o.head<2>() - origin_) / cell_;
  int cx = static_cast<int>(std::floor(p.x())), cy = static_cast<int>(std::floor(p.y()));
  const Eigen::Vector2f dir = d.head<2>();
  const int sx = dir.x() > 0 ? 1 : -1, sy = dir.y() > 0 ? 1 : -1;
  const float tdx = std::abs(cell_ / (dir.x() == 0.f ? 1e-12f : dir.x()));
  const float tdy = std::abs(cell_ / (dir.y() == 0.f ? 1e-12f : dir.y()));
  float tx = dir.x() == 0.f ? 1e30f : ((sx > 0 ? cx + 1 - p.x() : p.x() - cx) * tdx);
  float ty = dir.y() == 0.f ? 1e30f : ((sy > 0 ? cy + 1 - p.y() : p.y() - cy) * tdy);
  float t_cell_start = 0.f;
  while (t_cell_start < t_best) {
    if (cx >= 0 && cy >= 0 && cx < nx_ && cy < ny_) {
      const size_t c = static_cast<size_t>(cy) * nx_ + cx;
      for (uint32_t k = cell_start_[c]; k < cell_start_[c + 1]; ++k) {
        const uint32_t item = cell_items_[k];
        const uint32_t kind = item >> 28, id = item & 0x0fffffffu;
        float t;
        bool h = false;
        float r = 0.f;
        if (kind == 0) h = hit_box(boxes_[id], o, inv, t), r = boxes_[id].reflectivity;
        else if (kind == 1) h = hit_cylinder(cylinders_[id], o, d, t), r = cylinders_[id].reflectivity;
        else h = hit_sphere(spheres_[id], o, d, t), r = spheres_[id].reflectivity;
        if (h && t < t_best) {
          t_best = t;
          refl = r;
          found = true;
        }
      }
    } else if ((sx > 0 && cx >= nx_) || (sx < 0 && cx < 0) || (sy > 0 && cy >= ny_) || (sy < 0 && cy < 0)) {
      break;  // left the grid for good
    }
    if (tx < ty) {
      t_cell_start = tx;
      tx += tdx;
      cx += sx;
    } else {
      t_cell_start = ty;
      ty += tdy;
      cy += sy;
    }
  }
  if (!found) return false;
  hit.range = t_best;
  hit.reflectivity = refl;
  return true;
}

}  // namespace gcmap::sim
