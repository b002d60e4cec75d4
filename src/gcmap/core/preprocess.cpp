#include "gcmap/core/preprocess.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>
#include <tbb/parallel_sort.h>

#include <Eigen/Eigenvalues>
#include <array>
#include <bit>
#include <utility>

#include "gcmap/core/error.hpp"
#include "gcmap/core/kdtree.hpp"

namespace gcmap {

namespace {

struct KeyedIndex {
  uint64_t key;
  uint32_t index;
};

struct WideKeyedIndex {
  std::array<int64_t, 3> key;
  uint32_t index;
  bool operator<(const WideKeyedIndex& o) const { return key < o.key || (key == o.key && index < o.index); }
};

// Stable LSD radix sort on the low key_bits bits of the keys, 11 bits per pass.
void radix_sort(std::vector<KeyedIndex>& keyed, int key_bits) {
  constexpr int kDigit = 11;
  constexpr size_t kBuckets = size_t{1} << kDigit;
  std::vector<KeyedIndex> scratch(keyed.size());
  std::vector<uint32_t> offsets(kBuckets);
  for (int shift = 0; shift < key_bits; shift += kDigit) {
    std::fill(offsets.begin(), offsets.end(), 0u);
    for (const KeyedIndex& k : keyed) ++offsets[(k.key >> shift) & (kBuckets - 1)];
    uint32_t sum = 0;
    for (uint32_t& o : offsets) sum += std::exchange(o, sum);
    for (const KeyedIndex& k : keyed) scratch[offsets[(k.key >> shift) & (kBuckets - 1)]++] = k;
    keyed.swap(scratch);
  }
}

template <typename Keyed>
PointCloud average_runs(const PointCloud& cloud, const std::vector<Keyed>& sorted) {
  std::vector<uint32_t> starts;
  starts.reserve(sorted.size() / 2 + 1);
  for (size_t i = 0; i < sorted.size(); ++i) {
    if (i == 0 || sorted[i].key != sorted[i - 1].key) starts.push_back(static_cast<uint32_t>(i));
  }
  starts.push_back(static_cast<uint32_t>(sorted.size()));
  const size_t n = starts.size() - 1;

  PointCloud out;
  out.points.resize(n);
  if (cloud.has_covs()) out.covs.resize(n);
  if (cloud.has_intensities()) out.intensities.resize(n);
  if (cloud.has_times()) out.times.resize(n);
  if (cloud.has_labels()) out.labels.resize(n);

  tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 1024), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t v = r.begin(); v != r.end(); ++v) {
      const uint32_t b = starts[v], e = starts[v + 1];
      const double inv = 1.0 / (e - b);
      Eigen::Vector3d sum = Eigen::Vector3d::Zero();
      for (uint32_t i = b; i < e; ++i) sum += cloud.points[sorted[i].index].template cast<double>();
      out.points[v] = (sum * inv).cast<float>();
      if (cloud.has_covs()) {
        Eigen::Matrix3d c = Eigen::Matrix3d::Zero();
        for (uint32_t i = b; i < e; ++i) c += cloud.covs[sorted[i].index].template cast<double>();
        out.covs[v] = (c * inv).cast<float>();
      }
      if (cloud.has_intensities()) {
        double s = 0;
        for (uint32_t i = b; i < e; ++i) s += cloud.intensities[sorted[i].index];
        out.intensities[v] = static_cast<float>(s * inv);
      }
      if (cloud.has_times()) {
        double s = 0;
        for (uint32_t i = b; i < e; ++i) s += cloud.times[sorted[i].index];
        out.times[v] = static_cast<float>(s * inv);
      }
      // A label is categorical: keep the first point's (smallest original index).
      if (cloud.has_labels()) out.labels[v] = cloud.labels[sorted[b].index];
    }
  });
  return out;
}

}  // namespace

PointCloud voxel_downsample(const PointCloud& cloud, double resolution) {
  if (!(resolution > 0.0)) throw Error("voxel_downsample: resolution must be positive");
  const size_t n = cloud.size();
  if (n == 0) return cloud;
  const double inv = 1.0 / resolution;

  // floor without a library call: this runs on every raw point.
  const auto coord = [inv](float v) {
    const double x = v * inv;
    const int64_t t = static_cast<int64_t>(x);
    return t - (x < static_cast<double>(t));
  };
  // The voxel bounding box from the points' extremes (floor is monotonic).
  using Extremes = std::pair<Eigen::Vector3f, Eigen::Vector3f>;
  const Extremes ext = tbb::parallel_reduce(
      tbb::blocked_range<size_t>(0, n, 4096), Extremes{cloud.points[0], cloud.points[0]},
      [&](const tbb::blocked_range<size_t>& r, Extremes e) {
        for (size_t i = r.begin(); i != r.end(); ++i) {
          e.first = e.first.cwiseMin(cloud.points[i]);
          e.second = e.second.cwiseMax(cloud.points[i]);
        }
        return e;
      },
      [](const Extremes& a, const Extremes& b) {
        return Extremes{a.first.cwiseMin(b.first), a.second.cwiseMax(b.second)};
      });
  std::array<int64_t, 6> box;
  for (int k = 0; k < 3; ++k) {
    box[k] = coord(ext.first[k]);
    box[k + 3] = coord(ext.second[k]);
  }

  // Common case: the offsets pack into one key of at most 63 bits, sorted by a stable LSD radix sort
  // (ties keep index order, as the comparison sort below does).
  int bits[3];
  for (int k = 0; k < 3; ++k) bits[k] = std::bit_width(static_cast<uint64_t>(box[k + 3] - box[k]));
  if (bits[0] + bits[1] + bits[2] <= 63) {
    std::vector<KeyedIndex> keyed(n);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 4096), [&](const tbb::blocked_range<size_t>& r) {
      for (size_t i = r.begin(); i != r.end(); ++i) {
        const Eigen::Vector3f& p = cloud.points[i];
        const uint64_t x = static_cast<uint64_t>(coord(p.x()) - box[0]);
        const uint64_t y = static_cast<uint64_t>(coord(p.y()) - box[1]);
        const uint64_t z = static_cast<uint64_t>(coord(p.z()) - box[2]);
        keyed[i] = {(x << (bits[1] + bits[2])) | (y << bits[2]) | z, static_cast<uint32_t>(i)};
      }
    });
    radix_sort(keyed, bits[0] + bits[1] + bits[2]);
    return average_runs(cloud, keyed);
  }
  std::vector<WideKeyedIndex> keyed(n);
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Vector3f& p = cloud.points[i];
    keyed[i] = {{coord(p.x()), coord(p.y()), coord(p.z())}, static_cast<uint32_t>(i)};
  }
  tbb::parallel_sort(keyed.begin(), keyed.end());
  return average_runs(cloud, keyed);
}

PointCloud range_filter(const PointCloud& cloud, double min_range, double max_range) {
  std::vector<char> keep(cloud.size());
  const double min2 = min_range * min_range, max2 = max_range * max_range;
  for (size_t i = 0; i < cloud.size(); ++i) {
    const double d2 = cloud.points[i].cast<double>().squaredNorm();
    keep[i] = d2 >= min2 && d2 <= max2;
  }
  return cloud.selected(keep);
}

size_t remove_non_finite(PointCloud& cloud) {
  std::vector<char> keep(cloud.size());
  size_t dropped = 0;
  for (size_t i = 0; i < cloud.size(); ++i) {
    keep[i] = cloud.points[i].allFinite();
    dropped += !keep[i];
  }
  if (dropped) cloud.filter(keep);
  return dropped;
}

void estimate_covariances(PointCloud& cloud, const CovarianceConfig& config) {
  if (config.num_neighbors < 1) throw Error("estimate_covariances: num_neighbors must be >= 1");
  const size_t n = cloud.size();
  cloud.covs.resize(n);
  if (n == 0) return;
  const KdTree tree(cloud.points);
  const size_t k = static_cast<size_t>(config.num_neighbors);
  const Eigen::Vector3d regularized(config.epsilon, 1.0, 1.0);

  tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 256), [&](const tbb::blocked_range<size_t>& r) {
    std::vector<uint32_t> idx(k);
    std::vector<float> d2(k);
    for (size_t i = r.begin(); i != r.end(); ++i) {
      const size_t found = tree.knn(cloud.points[i], k, idx.data(), d2.data());
      if (found < 4) {
        cloud.covs[i] = Eigen::Matrix3f::Identity() * 0.01f;
        continue;
      }
      Eigen::Vector3d sum = Eigen::Vector3d::Zero();
      Eigen::Matrix3d sum2 = Eigen::Matrix3d::Zero();
      for (size_t j = 0; j < found; ++j) {
        const Eigen::Vector3d p = (cloud.points[idx[j]] - cloud.points[i]).cast<double>();
        sum += p;
        sum2 += p * p.transpose();
      }
      const Eigen::Vector3d mean = sum / found;
      const Eigen::Matrix3d cov = sum2 / found - mean * mean.transpose();
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig;
      eig.computeDirect(cov);
      // Eigenvalues ascending: the smallest direction is the surface normal.
      const Eigen::Matrix3d& U = eig.eigenvectors();
      Eigen::Matrix3d C = U * regularized.asDiagonal() * U.transpose();
      if (config.elevation_sigma > 0.0) {
        const Eigen::Vector3d q = cloud.points[i].cast<double>();
        const double h = std::max(q.head<2>().norm(), 1e-6);
        // d q / d elevation: along the vertical plane of the beam, as long as the range.
        const Eigen::Vector3d v(-q.z() * q.x() / h, -q.z() * q.y() / h, h);
        C += config.elevation_sigma * config.elevation_sigma * v * v.transpose();
      }
      cloud.covs[i] = C.cast<float>();
    }
  });
}

}  // namespace gcmap
