#include "gcmap/eval/map_entropy.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>
#include <tbb/parallel_sort.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <mutex>
#include <optional>

#include "gcmap/core/error.hpp"

namespace gcmap {
namespace {

// Points bucketed into cubic cells and sorted by a packed (x, y, z) cell key. Cells along z are
// adjacent in key order, so the cells of one (x, y) column within a z range form a single
// contiguous run of points: a radius query touches (2 reach + 1)^2 runs, with no hashing.
struct CellGrid {
  static constexpr int kBits = 21;
  static constexpr int64_t kMax = (int64_t{1} << kBits) - 1;

  double cell = 0.0;
  int reach = 0;  // cells per radius
  Eigen::Vector3d origin;
  std::vector<uint64_t> cell_keys;   // sorted, unique
  std::vector<uint32_t> cell_begin;  // size cell_keys.size() + 1, indices into x, y, z
  std::vector<float> x, y, z;        // points in cell order, relative to origin (SoA for the inner loop)

  static uint64_t pack(int64_t cx, int64_t cy, int64_t cz) {
    return (static_cast<uint64_t>(cx) << (2 * kBits)) | (static_cast<uint64_t>(cy) << kBits) | static_cast<uint64_t>(cz);
  }

  CellGrid(const std::vector<Eigen::Vector3f>& points, double radius) {
    Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::max());
    Eigen::Vector3d hi = -lo;
    for (const auto& p : points) {
      lo = lo.cwiseMin(p.cast<double>());
      hi = hi.cwiseMax(p.cast<double>());
    }
    origin = lo;
    // Half-radius cells scan ~15.6 r^3 per query instead of 27 r^3; grow them only for maps too
    // large to pack (the query stays exact because reach = ceil(radius / cell)).
    cell = std::max(radius / 2.0, (hi - lo).maxCoeff() / static_cast<double>(kMax - 1));
    reach = static_cast<int>(std::ceil(radius / cell - 1e-9));
    const size_t n = points.size();
    std::vector<std::pair<uint64_t, uint32_t>> keyed(n);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 4096), [&](const tbb::blocked_range<size_t>& r) {
      for (size_t i = r.begin(); i != r.end(); ++i) {
        const Eigen::Vector3d c = ((points[i].cast<double>() - origin) / cell).array().floor();
        keyed[i] = {pack(static_cast<int64_t>(c.x()), static_cast<int64_t>(c.y()), static_cast<int64_t>(c.z())),
                    static_cast<uint32_t>(i)};
      }
    });
    tbb::parallel_sort(keyed.begin(), keyed.end());
    x.resize(n);
    y.resize(n);
    z.resize(n);
    for (size_t i = 0; i < n; ++i) {
      const Eigen::Vector3f p = (points[keyed[i].second].cast<double>() - origin).cast<float>();
      x[i] = p.x();
      y[i] = p.y();
      z[i] = p.z();
      if (i == 0 || keyed[i].first != keyed[i - 1].first) {
        cell_keys.push_back(keyed[i].first);
        cell_begin.push_back(static_cast<uint32_t>(i));
      }
    }
    cell_begin.push_back(static_cast<uint32_t>(n));
  }

  // Point runs [begin, end) of the column cells around cell c, appended to `runs`.
  void neighbour_runs(size_t c, std::vector<std::pair<uint32_t, uint32_t>>& runs) const {
    const uint64_t key = cell_keys[c];
    const int64_t cx = static_cast<int64_t>(key >> (2 * kBits)), cy = static_cast<int64_t>((key >> kBits) & kMax),
                  cz = static_cast<int64_t>(key & kMax);
    const int64_t z0 = std::max<int64_t>(0, cz - reach), z1 = std::min<int64_t>(kMax, cz + reach);
    runs.clear();
    for (int64_t dx = -reach; dx <= reach; ++dx) {
      for (int64_t dy = -reach; dy <= reach; ++dy) {
        const int64_t nx = cx + dx, ny = cy + dy;
        if (nx < 0 || ny < 0 || nx > kMax || ny > kMax) continue;
        const auto first = std::lower_bound(cell_keys.begin(), cell_keys.end(), pack(nx, ny, z0));
        const auto last = std::upper_bound(first, cell_keys.end(), pack(nx, ny, z1));
        if (first == last) continue;
        runs.emplace_back(cell_begin[first - cell_keys.begin()], cell_begin[last - cell_keys.begin()]);
      }
    }
  }
};

// Zeroth, first and second moments of a set of points, as offsets from a query point.
struct Moments {
  double n = 0, s[3] = {0, 0, 0}, ss[6] = {0, 0, 0, 0, 0, 0};  // ss: xx xy xz yy yz zz
};

// The moments of the points within the radius of point q. Inlined: the hot loop of `mme`.
[[gnu::always_inline]] inline Moments moments_around(const CellGrid& grid, const std::vector<std::pair<uint32_t, uint32_t>>& runs,
                                                     uint32_t q, float r2) {
  const float qx = grid.x[q], qy = grid.y[q], qz = grid.z[q];
  // Offsets from the query point are small, so float sums per run lose nothing that matters; runs
  // are combined in double.
  Moments m;
  for (const auto& [b, e] : runs) {
    // Masked sums over four lanes at a time (Eigen packets), the tail one point at a time.
    using Lanes = Eigen::Array4f;
    Lanes acc[10];
    for (auto& v : acc) v.setZero();
    const auto add = [&](const auto& dx, const auto& dy, const auto& dz, const auto& mask) {
      const auto mx = (mask * dx).eval(), my = (mask * dy).eval(), mz = (mask * dz).eval();
      acc[0] += mask;
      acc[1] += mx;
      acc[2] += my;
      acc[3] += mz;
      acc[4] += mx * dx;
      acc[5] += mx * dy;
      acc[6] += mx * dz;
      acc[7] += my * dy;
      acc[8] += my * dz;
      acc[9] += mz * dz;
    };
    uint32_t j = b;
    for (; j + 4 <= e; j += 4) {
      const Lanes dx = Lanes::Map(&grid.x[j]) - qx, dy = Lanes::Map(&grid.y[j]) - qy, dz = Lanes::Map(&grid.z[j]) - qz;
      add(dx, dy, dz, (dx * dx + dy * dy + dz * dz <= r2).select(Lanes::Ones(), Lanes::Zero()));
    }
    for (; j != e; ++j) {
      Lanes dx = Lanes::Zero(), dy = Lanes::Zero(), dz = Lanes::Zero(), mask = Lanes::Zero();
      dx[0] = grid.x[j] - qx, dy[0] = grid.y[j] - qy, dz[0] = grid.z[j] - qz;
      mask[0] = dx[0] * dx[0] + dy[0] * dy[0] + dz[0] * dz[0] <= r2 ? 1.0f : 0.0f;
      add(dx, dy, dz, mask);
    }
    double sums[10];
    for (int k = 0; k < 10; ++k) sums[k] = acc[k].cast<double>().sum();
    m.n += sums[0];
    for (int k = 0; k < 3; ++k) m.s[k] += sums[1 + k];
    for (int k = 0; k < 6; ++k) m.ss[k] += sums[4 + k];
  }
  return m;
}

// The differential entropy of those points' Gaussian; nullopt when they are too few or flat.
std::optional<double> entropy(const Moments& m, int min_neighbors) {
  if (m.n < min_neighbors) return std::nullopt;
  const Eigen::Vector3d mean = Eigen::Vector3d(m.s[0], m.s[1], m.s[2]) / m.n;
  Eigen::Matrix3d cov;
  cov << m.ss[0], m.ss[1], m.ss[2], m.ss[1], m.ss[3], m.ss[4], m.ss[2], m.ss[4], m.ss[5];
  cov = cov / m.n - mean * mean.transpose();
  const double det = cov.determinant();
  if (!(det > 0.0)) return std::nullopt;
  return 0.5 * (3.0 * std::log(2.0 * M_PI * M_E) + std::log(det));
}

struct Acc {
  double sum = 0.0, sum2 = 0.0;
  size_t n = 0, skipped = 0;
};

}  // namespace

MapEntropy mean_map_entropy(const PointCloud& map, double radius, int min_neighbors, const EntropyProgress& progress) {
  if (!(radius > 0.0)) throw Error("--radius: must be positive");
  if (min_neighbors < 4) throw Error("--min-neighbors: must be at least 4");
  MapEntropy out;
  if (map.empty()) return out;
  for (const auto& p : map.points) {
    if (!p.allFinite()) throw Error("mean_map_entropy: the map has non-finite points");
  }
  const CellGrid grid(map.points, radius);
  const float r2 = static_cast<float>(radius * radius);
  std::atomic<size_t> done{0};
  std::mutex reporting;
  const auto report = [&](size_t points) {
    done += points;
    std::unique_lock<std::mutex> lock(reporting, std::try_to_lock);  // a busy reporter is not waited for
    if (lock) progress(done.load(), map.size());
  };
  const Acc acc = tbb::parallel_deterministic_reduce(
      tbb::blocked_range<size_t>(0, grid.cell_keys.size(), 16), Acc{},
      [&](const tbb::blocked_range<size_t>& r, Acc a) {
        std::vector<std::pair<uint32_t, uint32_t>> runs;
        for (size_t c = r.begin(); c != r.end(); ++c) {
          grid.neighbour_runs(c, runs);
          for (uint32_t i = grid.cell_begin[c]; i != grid.cell_begin[c + 1]; ++i) {
            const std::optional<double> h = entropy(moments_around(grid, runs, i, r2), min_neighbors);
            if (!h) {
              ++a.skipped;
              continue;
            }
            a.sum += *h;
            a.sum2 += *h * *h;
            ++a.n;
          }
        }
        if (progress) report(grid.cell_begin[r.end()] - grid.cell_begin[r.begin()]);
        return a;
      },
      [](Acc a, const Acc& b) {
        a.sum += b.sum;
        a.sum2 += b.sum2;
        a.n += b.n;
        a.skipped += b.skipped;
        return a;
      });
  out.num_points = acc.n;
  out.num_skipped = acc.skipped;
  if (acc.n) {
    out.mean = acc.sum / acc.n;
    out.stddev = std::sqrt(std::max(0.0, acc.sum2 / acc.n - out.mean * out.mean));
  }
  return out;
}

}  // namespace gcmap
