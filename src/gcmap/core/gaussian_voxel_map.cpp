#include "gcmap/core/gaussian_voxel_map.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include <limits>

#include "gcmap/core/error.hpp"

namespace gcmap {

GaussianVoxelMap::GaussianVoxelMap(double resolution, Updates updates)
    : resolution_(resolution), inv_resolution_(static_cast<float>(1.0 / resolution)), updates_(updates) {
  if (!(resolution > 0.0) || !std::isfinite(resolution)) throw Error("voxel map resolution must be positive");
  rehash(1024);
}

void GaussianVoxelMap::rehash(size_t capacity) {
  slots_.assign(capacity, Slot{0, 0, 0, -1});
  mask_ = static_cast<uint32_t>(capacity - 1);
  for (size_t v = 0; v < coords_.size(); ++v) {
    uint32_t slot = hash_voxel(coords_[v]) & mask_;
    while (slots_[slot].index >= 0) slot = (slot + 1) & mask_;
    slots_[slot] = {coords_[v].x(), coords_[v].y(), coords_[v].z(), static_cast<int32_t>(v)};
  }
}

int GaussianVoxelMap::find_or_insert(const Eigen::Vector3i& coord) {
  // Load factor at most 1/2 keeps probe sequences short.
  if (2 * (coords_.size() + 1) > slots_.size()) rehash(slots_.size() * 2);
  uint32_t slot = hash_voxel(coord) & mask_;
  while (true) {
    Slot& s = slots_[slot];
    if (s.index < 0) {
      s = {coord.x(), coord.y(), coord.z(), static_cast<int32_t>(coords_.size())};
      coords_.push_back(coord);
      counts_.push_back(0);
      sum_means_.push_back(Eigen::Vector3d::Zero());
      sum_covs_.push_back(Eigen::Matrix3d::Zero());
      return s.index;
    }
    if (s.x == coord.x() && s.y == coord.y() && s.z == coord.z()) return s.index;
    slot = (slot + 1) & mask_;
  }
}

void GaussianVoxelMap::insert(const PointCloud& cloud, const Eigen::Isometry3d& T) {
  if (!cloud.has_covs()) throw Error("voxel map insert: the cloud has no covariances");
  if (finalized_ && updates_ == Updates::once) throw Error("voxel map insert: the map was built once (Updates::once)");
  const Eigen::Matrix3d R = T.linear();
  const Eigen::Vector3d t = T.translation();
  for (size_t i = 0; i < cloud.size(); ++i) {
    const Eigen::Vector3d p = R * cloud.points[i].cast<double>() + t;
    const int v = find_or_insert(voxel_coord(p.cast<float>(), inv_resolution_));
    counts_[v] += 1;
    sum_means_[v] += p;
    sum_covs_[v] += R * cloud.covs[i].cast<double>() * R.transpose();
  }
}

void GaussianVoxelMap::remove(const PointCloud& cloud, const Eigen::Isometry3d& T) {
  if (!cloud.has_covs()) throw Error("voxel map remove: the cloud has no covariances");
  if (finalized_ && updates_ == Updates::once) throw Error("voxel map remove: the map was built once (Updates::once)");
  const Eigen::Matrix3d R = T.linear();
  const Eigen::Vector3d t = T.translation();
  for (size_t i = 0; i < cloud.size(); ++i) {
    const Eigen::Vector3d p = R * cloud.points[i].cast<double>() + t;
    const int v = find(voxel_coord(p.cast<float>(), inv_resolution_));
    if (v < 0 || counts_[v] == 0) throw Error("voxel map remove: the cloud was not inserted with this pose");
    if (--counts_[v] == 0) {
      // Exact zeros: what rounding left would bias the voxel if it fills again.
      sum_means_[v].setZero();
      sum_covs_[v].setZero();
      has_empty_ = true;
      continue;
    }
    sum_means_[v] -= p;
    sum_covs_[v] -= R * cloud.covs[i].cast<double>() * R.transpose();
  }
}

void GaussianVoxelMap::drop_empty_voxels() {
  size_t kept = 0;
  for (size_t v = 0; v < coords_.size(); ++v) {
    if (counts_[v] == 0) continue;
    coords_[kept] = coords_[v];
    counts_[kept] = counts_[v];
    sum_means_[kept] = sum_means_[v];
    sum_covs_[kept] = sum_covs_[v];
    ++kept;
  }
  coords_.resize(kept);
  counts_.resize(kept);
  sum_means_.resize(kept);
  sum_covs_.resize(kept);
  rehash(slots_.size());
  has_empty_ = false;
}

void GaussianVoxelMap::finalize() {
  if (has_empty_) drop_empty_voxels();
  means_.resize(coords_.size());
  covs_.resize(coords_.size());
  Eigen::Vector3i lo = Eigen::Vector3i::Constant(std::numeric_limits<int>::max()), hi = -lo;
  for (size_t v = 0; v < coords_.size(); ++v) {
    means_[v] = (sum_means_[v] / counts_[v]).cast<float>();
    covs_[v] = (sum_covs_[v] / counts_[v]).cast<float>();
    lo = lo.cwiseMin(coords_[v]);
    hi = hi.cwiseMax(coords_[v]);
  }
  const float res = static_cast<float>(resolution_);
  bounds_.setEmpty();
  if (!coords_.empty()) bounds_ = {lo.cast<float>() * res, (hi + Eigen::Vector3i::Ones()).cast<float>() * res};
  finalized_ = true;
  if (updates_ == Updates::once) {
    std::vector<Eigen::Vector3d>().swap(sum_means_);
    std::vector<Eigen::Matrix3d>().swap(sum_covs_);
  }
}

size_t GaussianVoxelMap::memory_bytes() const {
  return slots_.capacity() * sizeof(Slot) + coords_.capacity() * sizeof(Eigen::Vector3i) + counts_.capacity() * sizeof(int) +
         sum_means_.capacity() * sizeof(Eigen::Vector3d) + sum_covs_.capacity() * sizeof(Eigen::Matrix3d) +
         means_.capacity() * sizeof(Eigen::Vector3f) + covs_.capacity() * sizeof(Eigen::Matrix3f);
}

double overlap(const PointCloud& source, const GaussianVoxelMap& target, const Eigen::Isometry3d& T) {
  if (source.empty()) return 0.0;
  const PointTransform X(T);
  const size_t hits = tbb::parallel_reduce(
      tbb::blocked_range<size_t>(0, source.size(), 2048), size_t{0},
      [&](const tbb::blocked_range<size_t>& r, size_t acc) {
        for (size_t i = r.begin(); i != r.end(); ++i) acc += target.lookup(X * source.points[i]) >= 0;
        return acc;
      },
      [](size_t a, size_t b) { return a + b; });
  return static_cast<double>(hits) / static_cast<double>(source.size());
}

bool may_overlap(const Eigen::AlignedBox3f& source_box, const GaussianVoxelMap& target, const Eigen::Isometry3d& T) {
  if (source_box.isEmpty() || target.bounds().isEmpty()) return false;
  Eigen::AlignedBox3d reach;  // the source box's corners in the target frame
  const Eigen::AlignedBox3d box = source_box.cast<double>();
  for (int k = 0; k < 8; ++k) reach.extend(T * box.corner(static_cast<Eigen::AlignedBox3d::CornerType>(k)));
  const Eigen::Vector3d spare = Eigen::Vector3d::Constant(target.resolution());
  const Eigen::AlignedBox3d voxels(target.bounds().min().cast<double>() - spare, target.bounds().max().cast<double>() + spare);
  return reach.intersects(voxels);
}

}  // namespace gcmap
