#include "gcmap/mapping/occupancy_grid.hpp"

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <utility>

#include "gcmap/core/error.hpp"

namespace gcmap {

namespace {

constexpr float kNoGround = std::numeric_limits<float>::infinity();
constexpr double kMaxCells = 1.5e9;   // 6 GB of counts
constexpr size_t kGroundSupport = 3;  // returns of one scan that make a column's ground
constexpr float kGroundBand = 0.25f;  // m: within which they must lie

void bump(uint16_t& count) {
  std::atomic_ref<uint16_t> a(count);
  if (a.load(std::memory_order_relaxed) < 65535) a.fetch_add(1, std::memory_order_relaxed);
}

void lower_to(float& target, float z) {
  std::atomic_ref<float> a(target);
  float now = a.load(std::memory_order_relaxed);
  while (z < now && !a.compare_exchange_weak(now, z, std::memory_order_relaxed)) {}
}

}  // namespace

// Which cells this scan has already counted: stamp 2 * scan (passed) or 2 * scan + 1 (hit), over a
// window around the scan's origins, so that stale stamps of earlier scans never match.
struct OccupancyGridBuilder::Scratch {
  std::vector<uint32_t> stamp;
  std::vector<std::pair<uint32_t, float>> column_z;  // add_ground: (ground column, height) of a scan's returns
  int64_t wx0 = 0, wy0 = 0;
  int ww = 0, wh = 0;
  uint32_t scan = 0;
};
struct OccupancyGridBuilder::ScratchPool {
  tbb::enumerable_thread_specific<Scratch> threads;
};

OccupancyGridBuilder::OccupancyGridBuilder(const Eigen::AlignedBox2d& bounds, const GridOptions& options)
    : o_(options), scratch_(std::make_unique<ScratchPool>()) {
  if (!(o_.resolution > 0.0)) throw Error("--grid-resolution: must be > 0");
  if (!(o_.height_min < o_.height_max)) throw Error("--grid-height: MIN must be below MAX");
  x0_ = static_cast<int64_t>(std::floor(bounds.min().x() / o_.resolution));
  y0_ = static_cast<int64_t>(std::floor(bounds.min().y() / o_.resolution));
  const double w = std::ceil(bounds.max().x() / o_.resolution) - x0_ + 1,
               h = std::ceil(bounds.max().y() / o_.resolution) - y0_ + 1;
  if (w * h > kMaxCells)
    throw Error("--grid-resolution: " + std::to_string(o_.resolution) + " m over " + std::to_string(bounds.sizes().x()) + " x " +
                std::to_string(bounds.sizes().y()) + " m needs " + std::to_string(static_cast<int64_t>(w * h)) +
                " cells; choose a coarser resolution");
  width_ = static_cast<int>(w);
  height_ = static_cast<int>(h);
  cells_.resize(static_cast<size_t>(width_) * height_);
  gw_ = static_cast<int>(std::ceil(w * o_.resolution / o_.ground_cell)) + 1;
  gh_ = static_cast<int>(std::ceil(h * o_.resolution / o_.ground_cell)) + 1;
  ground_min_.assign(static_cast<size_t>(gw_) * gh_, kNoGround);
}

OccupancyGridBuilder::~OccupancyGridBuilder() = default;

namespace {
// The planar distance of a ray, checked against the ranges.
bool in_range(const Eigen::Vector3f& o, const Eigen::Vector3f& p, const GridOptions& g) {
  const float d2 = (p.head<2>() - o.head<2>()).squaredNorm();
  return d2 <= g.max_range * g.max_range && d2 >= g.min_range * g.min_range;
}
}  // namespace

void OccupancyGridBuilder::add_ground(const RayBatch& b) {
  Scratch& s = scratch_->threads.local();
  s.column_z.clear();
  const double gx0 = x0_ * o_.resolution, gy0 = y0_ * o_.resolution;
  for (size_t i = 0; i < b.ends.size(); ++i) {
    const Eigen::Vector3f& p = b.ends[i];
    if (!in_range(b.origins[b.origin_of[i]], p, o_)) continue;
    const int gx = static_cast<int>(std::floor((p.x() - gx0) / o_.ground_cell));
    const int gy = static_cast<int>(std::floor((p.y() - gy0) / o_.ground_cell));
    if (gx < 0 || gy < 0 || gx >= gw_ || gy >= gh_) continue;
    s.column_z.emplace_back(static_cast<uint32_t>(gy) * gw_ + gx, p.z());
  }
  std::sort(s.column_z.begin(), s.column_z.end());
  // Per column the lowest return that kGroundSupport returns of this scan confirm: a stray return
  // beyond the ground (multipath, a spurious echo) stands alone and would sink the column.
  for (size_t i = 0; i < s.column_z.size();) {
    size_t end = i;
    while (end < s.column_z.size() && s.column_z[end].first == s.column_z[i].first) ++end;
    for (size_t k = i; k + kGroundSupport - 1 < end; ++k)
      if (s.column_z[k + kGroundSupport - 1].second - s.column_z[k].second <= kGroundBand) {
        lower_to(ground_min_[s.column_z[i].first], s.column_z[k].second);
        break;
      }
    i = end;
  }
}

void OccupancyGridBuilder::finish_ground() {
  ground_.assign(ground_min_.size(), kNoGround);
  tbb::parallel_for(0, gh_, [&](int y) {
    for (int x = 0; x < gw_; ++x) {
      float m = kNoGround;
      for (int v = std::max(0, y - 1); v <= std::min(gh_ - 1, y + 1); ++v)
        for (int u = std::max(0, x - 1); u <= std::min(gw_ - 1, x + 1); ++u)
          m = std::min(m, ground_min_[static_cast<size_t>(v) * gw_ + u]);
      ground_[static_cast<size_t>(y) * gw_ + x] = m;
    }
  });
}

bool OccupancyGridBuilder::usable(const RayBatch& b, size_t i, float& height_above, float& ground) const {
  const Eigen::Vector3f& p = b.ends[i];
  if (!in_range(b.origins[b.origin_of[i]], p, o_)) return false;
  const int gx = static_cast<int>(std::floor((p.x() - x0_ * o_.resolution) / o_.ground_cell));
  const int gy = static_cast<int>(std::floor((p.y() - y0_ * o_.resolution) / o_.ground_cell));
  if (gx < 0 || gy < 0 || gx >= gw_ || gy >= gh_) return false;
  ground = ground_[static_cast<size_t>(gy) * gw_ + gx];
  height_above = p.z() - ground;
  return ground != kNoGround;
}

void OccupancyGridBuilder::visit(int cx, int cy, Scratch& s) const {
  const int64_t lx = cx + x0_ - s.wx0, ly = cy + y0_ - s.wy0;
  if (cx < 0 || cy < 0 || cx >= width_ || cy >= height_ || lx < 0 || ly < 0 || lx >= s.ww || ly >= s.wh) return;
  uint32_t& stamp = s.stamp[static_cast<size_t>(ly) * s.ww + lx];
  if (stamp >> 1 == s.scan) return;  // counted in this scan already (passed or hit)
  stamp = 2 * s.scan;
  bump(cells_[static_cast<size_t>(cy) * width_ + cx].passes);
}

// Walks the cells of the part of the ray no higher than the band (Amanatides and Woo), leaving
// out the end cell of a hit.
void OccupancyGridBuilder::cast(const Eigen::Vector3f& o, const Eigen::Vector3f& p, float ground, bool hit, Scratch& s) const {
  const float ho = o.z() - ground, hp = p.z() - ground, top = o_.height_max;
  if (ho > top && hp > top) return;
  double t0 = 0.0, t1 = 1.0;
  if (ho > top) t0 = (ho - top) / (ho - hp);
  else if (hp > top) t1 = (top - ho) / (hp - ho);
  const Eigen::Vector2d a = o.head<2>().cast<double>() + t0 * (p - o).head<2>().cast<double>();
  const Eigen::Vector2d b = o.head<2>().cast<double>() + t1 * (p - o).head<2>().cast<double>();
  const double ax = a.x() / o_.resolution - x0_, ay = a.y() / o_.resolution - y0_;
  const double bx = b.x() / o_.resolution - x0_, by = b.y() / o_.resolution - y0_;
  int cx = static_cast<int>(std::floor(ax)), cy = static_cast<int>(std::floor(ay));
  const int n = std::abs(static_cast<int>(std::floor(bx)) - cx) + std::abs(static_cast<int>(std::floor(by)) - cy);
  const double dx = bx - ax, dy = by - ay, inf = std::numeric_limits<double>::infinity();
  const int sx = dx > 0 ? 1 : -1, sy = dy > 0 ? 1 : -1;
  const double tdx = dx != 0 ? 1.0 / std::abs(dx) : inf, tdy = dy != 0 ? 1.0 / std::abs(dy) : inf;
  double tmx = dx != 0 ? (sx > 0 ? cx + 1 - ax : ax - cx) * tdx : inf;
  double tmy = dy != 0 ? (sy > 0 ? cy + 1 - ay : ay - cy) * tdy : inf;
  const int cells = hit ? n : n + 1;
  for (int k = 0; k < cells; ++k) {
    visit(cx, cy, s);
    if (tmx < tmy) tmx += tdx, cx += sx;
    else tmy += tdy, cy += sy;
  }
}

void OccupancyGridBuilder::add_rays(const RayBatch& b) {
  if (b.ends.empty()) return;
  Scratch& s = scratch_->threads.local();
  Eigen::AlignedBox2f box;
  for (const Eigen::Vector3f& o : b.origins) box.extend(o.head<2>());
  const int64_t reach = static_cast<int64_t>(std::ceil(o_.max_range / o_.resolution)) + 2;
  s.wx0 = static_cast<int64_t>(std::floor(box.min().x() / o_.resolution)) - reach;
  s.wy0 = static_cast<int64_t>(std::floor(box.min().y() / o_.resolution)) - reach;
  s.ww = static_cast<int>(static_cast<int64_t>(std::ceil(box.max().x() / o_.resolution)) + reach - s.wx0 + 1);
  s.wh = static_cast<int>(static_cast<int64_t>(std::ceil(box.max().y() / o_.resolution)) + reach - s.wy0 + 1);
  if (s.stamp.size() < static_cast<size_t>(s.ww) * s.wh) s.stamp.resize(static_cast<size_t>(s.ww) * s.wh, 0);
  s.scan = next_scan_.fetch_add(1);
  float h, g;
  for (size_t i = 0; i < b.ends.size(); ++i) {  // hits first: they win over passes of this scan
    if (!usable(b, i, h, g) || h < o_.height_min || h > o_.height_max) continue;
    const int cx = static_cast<int>(std::floor(b.ends[i].x() / o_.resolution) - x0_);
    const int cy = static_cast<int>(std::floor(b.ends[i].y() / o_.resolution) - y0_);
    const int64_t lx = cx + x0_ - s.wx0, ly = cy + y0_ - s.wy0;
    if (cx < 0 || cy < 0 || cx >= width_ || cy >= height_ || lx < 0 || ly < 0 || lx >= s.ww || ly >= s.wh) continue;
    uint32_t& stamp = s.stamp[static_cast<size_t>(ly) * s.ww + lx];
    if (stamp == 2 * s.scan + 1) continue;
    stamp = 2 * s.scan + 1;
    bump(cells_[static_cast<size_t>(cy) * width_ + cx].hits);
  }
  for (size_t i = 0; i < b.ends.size(); ++i)
    if (usable(b, i, h, g)) cast(b.origins[b.origin_of[i]], b.ends[i], g, h >= o_.height_min && h <= o_.height_max, s);
}

Occupancy OccupancyGridBuilder::state(const Cell& c) const {
  const int seen = c.hits + c.passes;
  if (c.hits >= o_.min_scans && c.hits >= o_.occupied_ratio * seen) return Occupancy::occupied;
  return c.passes >= o_.min_scans ? Occupancy::free : Occupancy::unknown;
}

OccupancyGrid OccupancyGridBuilder::grid() const {
  int x_lo = width_, y_lo = height_, x_hi = -1, y_hi = -1;
  for (int y = 0; y < height_; ++y)
    for (int x = 0; x < width_; ++x) {
      const Cell& c = cells_[static_cast<size_t>(y) * width_ + x];
      if (c.hits + c.passes == 0) continue;
      x_lo = std::min(x_lo, x), x_hi = std::max(x_hi, x), y_lo = std::min(y_lo, y), y_hi = std::max(y_hi, y);
    }
  OccupancyGrid g;
  g.resolution = o_.resolution;
  if (x_hi < 0) return g;  // no ray: an empty grid
  x_lo = std::max(0, x_lo - 1), y_lo = std::max(0, y_lo - 1);
  x_hi = std::min(width_ - 1, x_hi + 1), y_hi = std::min(height_ - 1, y_hi + 1);
  g.width = x_hi - x_lo + 1;
  g.height = y_hi - y_lo + 1;
  g.origin = Eigen::Vector2d((x0_ + x_lo) * o_.resolution, (y0_ + y_lo) * o_.resolution);
  g.cells.resize(static_cast<size_t>(g.width) * g.height);
  tbb::parallel_for(0, g.height, [&](int y) {
    for (int x = 0; x < g.width; ++x)
      g.cells[static_cast<size_t>(y) * g.width + x] = state(cells_[static_cast<size_t>(y + y_lo) * width_ + x + x_lo]);
  });
  return g;
}

}  // namespace gcmap
