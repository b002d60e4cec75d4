#include "gcmap/eval/map_entropy.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include <cmath>

#include "gcmap/core/error.hpp"
#include "gcmap/core/kdtree.hpp"

namespace gcmap {

MapEntropy mean_map_entropy(const PointCloud& map, double radius, int min_neighbors) {
  if (!(radius > 0.0)) throw Error("--radius: must be positive");
  if (min_neighbors < 4) throw Error("--min-neighbors: must be at least 4");
  MapEntropy out;
  if (map.empty()) return out;
  const KdTree tree(map.points);
  struct Acc {
    double sum = 0.0, sum2 = 0.0;
    size_t n = 0, skipped = 0;
  };
  const double log_2pie = std::log(2.0 * M_PI * M_E);
  const Acc acc = tbb::parallel_deterministic_reduce(
      tbb::blocked_range<size_t>(0, map.size(), 1024), Acc{},
      [&](const tbb::blocked_range<size_t>& r, Acc a) {
        std::vector<std::pair<uint32_t, float>> nb;
        for (size_t i = r.begin(); i != r.end(); ++i) {
          const size_t n = tree.radius(map.points[i], static_cast<float>(radius), nb);
          if (n < static_cast<size_t>(min_neighbors)) {
            ++a.skipped;
            continue;
          }
          Eigen::Vector3d mean = Eigen::Vector3d::Zero();
          Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
          for (const auto& [j, d2] : nb) {
            const Eigen::Vector3d p = (map.points[j] - map.points[i]).cast<double>();
            mean += p;
            cov += p * p.transpose();
          }
          mean /= n;
          cov = cov / n - mean * mean.transpose();
          const double det = cov.determinant();
          if (!(det > 0.0)) {
            ++a.skipped;
            continue;
          }
          const double h = 0.5 * (3.0 * log_2pie + std::log(det));
          a.sum += h;
          a.sum2 += h * h;
          ++a.n;
        }
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
