#include "gcmap/mapping/scan_context.hpp"

#include <nanoflann.hpp>

#include <algorithm>
#include <cmath>

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
  for (const auto& p : cloud.points) {
    const double r = std::hypot(p.x(), p.y());
    if (!(r < config.max_radius)) continue;  // also drops NaN
    const int ring = std::min(sc.rings - 1, static_cast<int>(r / ring_width));
    const int sector = std::min(sc.sectors - 1, static_cast<int>((std::atan2(p.y(), p.x()) + M_PI) / sector_width));
    float& cell = sc.cells[ring * sc.sectors + sector];
    cell = std::max(cell, static_cast<float>(p.z() + config.lidar_height));
  }
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
  ScanContextMatch best;
  for (int shift = 0; shift < S; ++shift) {
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
    if (d < best.distance) {
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
  bool kdtree_get_bbox(BBox&) const { return false; }
};

}  // namespace

ScanContextDatabase::Result ScanContextDatabase::query(const ScanContext& descriptor, size_t end, int num_candidates) const {
  Result best;
  end = std::min(end, places_.size());
  if (end == 0 || num_candidates < 1) return best;
  const RingKeys keys{places_, end};
  using Tree = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<float, RingKeys>, RingKeys, -1, uint32_t>;
  // Rebuilt per query: a few thousand 20-float keys build in well under a millisecond, and the
  // searchable range moves with every new place.
  Tree tree(descriptor.rings, keys, nanoflann::KDTreeSingleIndexAdaptorParams(10));
  tree.buildIndex();
  const size_t k = std::min(end, static_cast<size_t>(num_candidates));
  std::vector<uint32_t> idx(k);
  std::vector<float> d2(k);
  nanoflann::KNNResultSet<float, uint32_t> result(k);
  result.init(idx.data(), d2.data());
  tree.findNeighbors(result, descriptor.ring_key.data(), nanoflann::SearchParams());
  std::vector<uint32_t> found(idx.begin(), idx.begin() + result.size());
  std::sort(found.begin(), found.end());  // order-independent tie breaking
  for (const uint32_t i : found) {
    const ScanContextMatch m = match_scan_contexts(descriptor, places_[i]);
    if (m.distance < best.match.distance) best = {static_cast<int>(i), m};
  }
  return best;
}

}  // namespace gcmap
