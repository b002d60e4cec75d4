#include "gcmap/loop/scan_context.hpp"

#include <nanoflann.hpp>
#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "gcmap/core/error.hpp"

namespace gcmap {

ScanContext make_scan_context(const PointCloud& cloud, const ScanContextConfig& config) {
  if (config.rings < 1 || config.sectors < 1 || !(config.max_radius > 0.0))
    throw Error("scan context: rings, sectors and max_radius must be positive");
  ScanContext sc;
  sc.rings = config.rings;
  sc.sectors = config.sectors;
  sc.cells.assign(static_cast<size_t>(sc.rings) * sc.sectors, 0.f);
  const double ring_width = config.max_radius / sc.rings, sector_width = 2.0 * M_PI / sc.sectors;
  const float max_radius = static_cast<float>(config.max_radius), height = static_cast<float>(config.lidar_height);
  const float inv_ring = static_cast<float>(1.0 / ring_width), inv_sector = static_cast<float>(1.0 / sector_width);
  // Per-chunk grids merged by max: exact and independent of the thread count.
  sc.cells = tbb::parallel_reduce(
      tbb::blocked_range<size_t>(0, cloud.size(), 4096), sc.cells,
      [&](const tbb::blocked_range<size_t>& range, std::vector<float> cells) {
        for (size_t i = range.begin(); i != range.end(); ++i) {
          const Eigen::Vector3f& p = cloud.points[i];
          const float r = std::sqrt(p.x() * p.x() + p.y() * p.y());
          if (!(r < max_radius)) continue;  // also drops NaN
          const int ring = std::min(sc.rings - 1, static_cast<int>(r * inv_ring));
          const int sector =
              std::min(sc.sectors - 1, static_cast<int>((std::atan2(p.y(), p.x()) + static_cast<float>(M_PI)) * inv_sector));
          float& cell = cells[ring * sc.sectors + sector];
          cell = std::max(cell, p.z() + height);
        }
        return cells;
      },
      [](std::vector<float> a, const std::vector<float>& b) {
        for (size_t k = 0; k < a.size(); ++k) a[k] = std::max(a[k], b[k]);
        return a;
      });
  sc.ring_key.assign(sc.rings, 0.f);
  for (int r = 0; r < sc.rings; ++r) {
    double sum = 0.0;
    for (int s = 0; s < sc.sectors; ++s) sum += sc.at(r, s);
    sc.ring_key[r] = static_cast<float>(sum / sc.sectors);
  }
  return sc;
}

ScanContextMatch match_scan_contexts(const ScanContext& q, const ScanContext& c) {
  if (q.rings != c.rings || q.sectors != c.sectors) throw Error("scan context: descriptors of different shapes");
  const int R = q.rings, S = q.sectors;
  // Column norms once; every shift reuses them.
  std::vector<double> qn(S, 0.0), cn(S, 0.0);
  for (int s = 0; s < S; ++s) {
    for (int r = 0; r < R; ++r) {
      qn[s] += double(q.at(r, s)) * q.at(r, s);
      cn[s] += double(c.at(r, s)) * c.at(r, s);
    }
    qn[s] = std::sqrt(qn[s]);
    cn[s] = std::sqrt(cn[s]);
  }
  // Coarse alignment by the sector keys (column means), then the full distance only within
  // +-kRefine columns of it: 7 full evaluations instead of S.
  std::vector<double> qk(S, 0.0), ck(S, 0.0);
  for (int s = 0; s < S; ++s) {
    for (int r = 0; r < R; ++r) {
      qk[s] += q.at(r, s);
      ck[s] += c.at(r, s);
    }
  }
  int coarse = 0;
  double coarse_cost = std::numeric_limits<double>::max();
  for (int shift = 0; shift < S; ++shift) {
    double cost = 0.0;
    for (int s = 0; s < S; ++s) cost += std::abs(qk[s] - ck[(s + shift) % S]);
    if (cost < coarse_cost) {
      coarse_cost = cost;
      coarse = shift;
    }
  }
  constexpr int kRefine = 3;
  ScanContextMatch best;
  for (int k = -kRefine; k <= kRefine; ++k) {
    const int shift = ((coarse + k) % S + S) % S;
    double sum = 0.0;
    int valid = 0;
    for (int s = 0; s < S; ++s) {
      const int t = (s + shift) % S;
      if (qn[s] == 0.0 || cn[t] == 0.0) continue;
      double dot = 0.0;
      for (int r = 0; r < R; ++r) dot += double(q.at(r, s)) * c.at(r, t);
      sum += dot / (qn[s] * cn[t]);
      ++valid;
    }
    const double d = valid ? 1.0 - sum / valid : 1.0;
    if (d < best.distance || (d == best.distance && shift < best.shift)) {
      best.distance = d;
      best.shift = shift;
    }
  }
  // A point at azimuth a in the query lies in sector j; the candidate sees it in sector j + shift,
  // i.e. at azimuth a + shift * width.
  best.yaw = best.shift * 2.0 * M_PI / S;
  if (best.yaw > M_PI) best.yaw -= 2.0 * M_PI;
  return best;
}

namespace {

struct RingKeys {
  const std::vector<ScanContext>& places;
  size_t count;
  size_t kdtree_get_point_count() const { return count; }
  float kdtree_get_pt(size_t i, size_t dim) const { return places[i].ring_key[dim]; }
  template <class BBox>
  bool kdtree_get_bbox(BBox&) const {
    return false;
  }
};

}  // namespace

std::vector<ScanContextDatabase::Result> ScanContextDatabase::query(const std::vector<const ScanContext*>& descriptors,
                                                                    size_t end, int num_candidates) const {
  std::vector<Result> out(descriptors.size());
  end = std::min(end, places_.size());
  if (end == 0 || num_candidates < 1 || descriptors.empty()) return out;
  const RingKeys keys{places_, end};
  using Tree = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<float, RingKeys>, RingKeys, -1, uint32_t>;
  // Built per call, once for all queries: the searchable range grows with every submap.
  Tree tree(places_.front().rings, keys, nanoflann::KDTreeSingleIndexAdaptorParams(10));
  tree.buildIndex();
  const size_t k = std::min(end, static_cast<size_t>(num_candidates));
  std::vector<uint32_t> idx(k);
  std::vector<float> d2(k);
  for (size_t q = 0; q < descriptors.size(); ++q) {
    nanoflann::KNNResultSet<float, uint32_t> result(k);
    result.init(idx.data(), d2.data());
    tree.findNeighbors(result, descriptors[q]->ring_key.data(), nanoflann::SearchParams());
    std::vector<uint32_t> found(idx.begin(), idx.begin() + result.size());
    std::sort(found.begin(), found.end());  // order-independent tie breaking
    for (const uint32_t i : found) {
      const ScanContextMatch m = match_scan_contexts(*descriptors[q], places_[i]);
      if (m.distance < out[q].match.distance) out[q] = {static_cast<int>(i), m};
    }
  }
  return out;
}

}  // namespace gcmap
