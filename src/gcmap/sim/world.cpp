#include "gcmap/sim/world.hpp"

#include <algorithm>
#include <cmath>

#include "gcmap/sim/rng.hpp"

namespace gcmap::sim {

World::World(const Terrain& terrain, Eigen::Vector2f lo, Eigen::Vector2f hi)
    : terrain_(terrain), max_grad_(terrain.amp_x / terrain.len_x + terrain.amp_y / terrain.len_y + 1e-3f), origin_(lo) {
  nx_ = std::max(1, static_cast<int>(std::ceil((hi.x() - lo.x()) / cell_)));
  ny_ = std::max(1, static_cast<int>(std::ceil((hi.y() - lo.y()) / cell_)));
  build_cells_.assign(static_cast<size_t>(nx_) * ny_, {});
}

float World::ground_height(float x, float y) const {
  return terrain_.amp_x * std::sin(x / terrain_.len_x) + terrain_.amp_y * std::sin(y / terrain_.len_y + 0.7f);
}

Eigen::Vector2f World::ground_gradient(float x, float y) const {
  return {terrain_.amp_x / terrain_.len_x * std::cos(x / terrain_.len_x),
          terrain_.amp_y / terrain_.len_y * std::cos(y / terrain_.len_y + 0.7f)};
}

void World::finalize() {
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
    for (int y = cy0; y <= cy1; ++y)
      build_cells_[static_cast<size_t>(y) * nx_ + x].push_back((uint32_t(kind) << 28) | uint32_t(id));
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
void World::add_oriented_box(const OrientedBox& b) {
  const float r = b.half.head<2>().norm();
  index(3, static_cast<int>(oboxes_.size()), b.center.head<2>().array() - r, b.center.head<2>().array() + r);
  oboxes_.push_back(b);
}

bool World::ground_hit(const Eigen::Vector3f& o, const Eigen::Vector3f& d, float t_max, float& t) const {
  // Sphere tracing on h(t) = z(t) - g(x(t), y(t)): |dh/dt| <= L, so a step of h/L never overshoots.
  const float L = std::abs(d.z()) + max_grad_ * d.head<2>().norm();
  t = 0.f;
  for (int it = 0; it < terrain_.trace_steps && t < t_max; ++it) {
    const Eigen::Vector3f p = o + t * d;
    const float h = p.z() - ground_height(p.x(), p.y());
    if (h < 2e-3f) return true;
    t += std::max(h / L, 1e-3f);
  }
  return false;
}

bool intersect_box(const Eigen::Vector3f& lo, const Eigen::Vector3f& hi, const Eigen::Vector3f& o, const Eigen::Vector3f& inv,
                   float& t, int& axis) {
  float t0 = 0.f, t1 = 1e30f;
  axis = 0;
  for (int k = 0; k < 3; ++k) {
    float a = (lo[k] - o[k]) * inv[k], c = (hi[k] - o[k]) * inv[k];
    if (a > c) std::swap(a, c);
    if (a > t0) t0 = a, axis = k;
    t1 = std::min(t1, c);
    if (t0 > t1) return false;
  }
  if (t0 <= 0.f) return false;  // origin inside: ignore
  t = t0;
  return true;
}

namespace {
inline bool hit_sphere(const Sphere& s, const Eigen::Vector3f& o, const Eigen::Vector3f& d, float& t, float& chord) {
  const Eigen::Vector3f m = o - s.center;
  const float b = m.dot(d), c = m.squaredNorm() - s.radius * s.radius;
  const float disc = b * b - c;
  if (disc < 0.f) return false;
  t = -b - std::sqrt(disc);
  chord = 2.f * std::sqrt(disc);
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

namespace {
bool overlaps(float a0, float a1, float b0, float b1) { return a0 <= b1 && b0 <= a1; }
}  // namespace

bool World::item_in_column(uint32_t item, const Eigen::Vector2f& p, float z0, float z1) const {
  const uint32_t kind = item >> 28, id = item & 0x0fffffffu;
  if (kind == 0) {
    const Box& b = boxes_[id];
    const bool always = std::isinf(b.t_begin) && std::isinf(b.t_end);
    return always && (p.array() >= b.min.head<2>().array()).all() && (p.array() <= b.max.head<2>().array()).all() &&
           overlaps(b.min.z(), b.max.z(), z0, z1);
  }
  if (kind == 1) {
    const Cylinder& c = cylinders_[id];
    return (p - c.center).squaredNorm() <= c.radius * c.radius && overlaps(c.z0, c.z1, z0, z1);
  }
  if (kind == 2) {
    const Sphere& s = spheres_[id];
    const float r2 = s.radius * s.radius - (p - s.center.head<2>()).squaredNorm();
    if (s.porosity > 0.f || r2 < 0.f) return false;
    return overlaps(s.center.z() - std::sqrt(r2), s.center.z() + std::sqrt(r2), z0, z1);
  }
  const OrientedBox& b = oboxes_[id];
  const Eigen::Vector2f m = p - b.center.head<2>();
  const float c = std::cos(b.yaw), sn = std::sin(b.yaw);
  const Eigen::Vector2f l(c * m.x() + sn * m.y(), -sn * m.x() + c * m.y());
  return std::abs(l.x()) <= b.half.x() && std::abs(l.y()) <= b.half.y() &&
         overlaps(b.center.z() - b.half.z(), b.center.z() + b.half.z(), z0, z1);
}

bool World::column_solid(float x, float y, float z0, float z1) const {
  const Eigen::Vector2f p(x, y), q = (p - origin_) / cell_;
  const int cx = static_cast<int>(std::floor(q.x())), cy = static_cast<int>(std::floor(q.y()));
  if (cx < 0 || cy < 0 || cx >= nx_ || cy >= ny_) return false;
  const size_t c = static_cast<size_t>(cy) * nx_ + cx;
  for (uint32_t i = cell_start_[c]; i < cell_start_[c + 1]; ++i)
    if (item_in_column(cell_items_[i], p, z0, z1)) return true;
  return false;
}

bool World::hit_item(uint32_t item, const Eigen::Vector3f& o, const Eigen::Vector3f& d, const Eigen::Vector3f& inv,
                     const RayContext& ctx, float& t, Hit& h) const {
  const uint32_t kind = item >> 28, id = item & 0x0fffffffu;
  int axis = 0;
  if (kind == 0) {
    const Box& b = boxes_[id];
    if (ctx.time < b.t_begin || ctx.time >= b.t_end || !intersect_box(b.min, b.max, o, inv, t, axis)) return false;
    h = Hit{t, b.reflectivity, b.label, std::abs(d[axis])};
  } else if (kind == 1) {
    const Cylinder& c = cylinders_[id];
    if (!hit_cylinder(c, o, d, t)) return false;
    const Eigen::Vector2f n = ((o + t * d).head<2>() - c.center) / c.radius;
    h = Hit{t, c.reflectivity, c.label, std::abs(n.dot(d.head<2>()))};
  } else if (kind == 2) {
    const Sphere& s = spheres_[id];
    float chord;
    if (!hit_sphere(s, o, d, t, chord)) return false;
    h = Hit{t, s.reflectivity, s.label, std::abs((o + t * d - s.center).dot(d)) / s.radius};
    if (s.porosity > 0.f) {
      // Leaves: the ray passes, or returns from somewhere in the first metre or so of foliage.
      const uint64_t r = hash_key(ctx.key, item);
      if (unit_float(r) < s.porosity) return false;
      t += unit_float(mix64(r)) * std::min(chord, 1.2f);
      h.range = t;
    }
  } else {
    const OrientedBox& b = oboxes_[id];
    const float c = std::cos(b.yaw), sn = std::sin(b.yaw);
    const Eigen::Vector3f m = o - b.center;
    const Eigen::Vector3f ol(c * m.x() + sn * m.y(), -sn * m.x() + c * m.y(), m.z());
    const Eigen::Vector3f dl(c * d.x() + sn * d.y(), -sn * d.x() + c * d.y(), d.z());
    const Eigen::Vector3f il(1.f / dl.x(), 1.f / dl.y(), 1.f / dl.z());
    if (!intersect_box(-b.half, b.half, ol, il, t, axis)) return false;
    h = Hit{t, b.reflectivity, b.label, std::abs(dl[axis])};
  }
  return true;
}

bool World::raycast(const Eigen::Vector3f& o, const Eigen::Vector3f& d, float max_range, Hit& hit, const RayContext& ctx) const {
  float t_best = max_range;
  bool found = false;
  float tg;
  if (ground_hit(o, d, max_range, tg) && tg < t_best) {
    t_best = tg;
    const Eigen::Vector3f p = o + tg * d;
    const Eigen::Vector2f g = ground_gradient(p.x(), p.y());
    const float cos_inc = std::abs(d.z() - g.x() * d.x() - g.y() * d.y()) / std::sqrt(1.f + g.squaredNorm());
    hit = Hit{tg, terrain_.reflectivity, terrain_.label, cos_inc};
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
        float t;
        Hit h;
        if (hit_item(cell_items_[k], o, d, inv, ctx, t, h) && t < t_best) {
          t_best = t;
          hit = h;
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
  return found;
}

}  // namespace gcmap::sim
