#pragma once
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>
#include <cstdint>
#include <vector>

#include "gcmap/core/point_cloud.hpp"

namespace gcmap {

// p -> R p + t in float, rounded step by step in a fixed order (no fused multiply-add): the CUDA
// kernels evaluate the same expression, so a point on a voxel border picks the same voxel there.
struct PointTransform {
  Eigen::Matrix3f R;
  Eigen::Vector3f t;
  explicit PointTransform(const Eigen::Isometry3d& T) : R(T.linear().cast<float>()), t(T.translation().cast<float>()) {}
  Eigen::Vector3f operator*(const Eigen::Vector3f& p) const {
    return {R(0, 0) * p.x() + R(0, 1) * p.y() + R(0, 2) * p.z() + t.x(),
            R(1, 0) * p.x() + R(1, 1) * p.y() + R(1, 2) * p.z() + t.y(),
            R(2, 0) * p.x() + R(2, 1) * p.y() + R(2, 2) * p.z() + t.z()};
  }
};

// floor() for values in int range: truncate, then step down for negative non-integers. Without
// SSE4.1 std::floor is a library call or a long emulation, and this is on every voxel lookup.
inline int floor_to_int(float x) {
  const int i = static_cast<int>(x);
  return i - (x < static_cast<float>(i));
}

// Integer voxel coordinate of a point at a given inverse resolution.
inline Eigen::Vector3i voxel_coord(const Eigen::Vector3f& p, float inv_resolution) {
  return Eigen::Vector3i(floor_to_int(p.x() * inv_resolution), floor_to_int(p.y() * inv_resolution),
                         floor_to_int(p.z() * inv_resolution));
}

inline uint32_t hash_voxel(const Eigen::Vector3i& c) {
  uint64_t h = static_cast<uint64_t>(static_cast<uint32_t>(c.x())) * 0x9E3779B185EBCA87ull;
  h ^= static_cast<uint64_t>(static_cast<uint32_t>(c.y())) * 0xC2B2AE3D27D4EB4Full;
  h ^= static_cast<uint64_t>(static_cast<uint32_t>(c.z())) * 0x165667B19E3779F9ull;
  return static_cast<uint32_t>(h ^ (h >> 29));
}

// Gaussian voxel map for VGICP. A voxel stores the mean of the point means and the mean of the
// point covariances that fell into it (aggregated distributions, not the scatter of the points),
// and the point count. Storage is a flat open-addressing table with linear probing.
class GaussianVoxelMap {
 public:
  // once: built by inserts and one finalize(), which frees the double accumulators (almost half
  // the map; a mapping run keeps hundreds of submap maps). incremental: keeps them, so clouds can
  // be inserted and removed after finalize() (the odometry's sliding window).
  enum class Updates { once, incremental };
  explicit GaussianVoxelMap(double resolution, Updates updates = Updates::once);

  double resolution() const { return resolution_; }
  float inv_resolution() const { return inv_resolution_; }
  size_t num_voxels() const { return means_.size(); }

  // Adds a cloud (with covariances) mapped by T_map_cloud. Call finalize() before lookups.
  void insert(const PointCloud& cloud, const Eigen::Isometry3d& T_map_cloud = Eigen::Isometry3d::Identity());
  // Takes back a cloud inserted earlier with the same T_map_cloud (a sliding window of frames
  // costs one frame per step instead of the whole window). Voxels left empty disappear at
  // finalize(), which then renumbers the voxels.
  void remove(const PointCloud& cloud, const Eigen::Isometry3d& T_map_cloud);
  void finalize();

  // Index of the voxel holding p, or -1.
  int lookup(const Eigen::Vector3f& p) const { return find(voxel_coord(p, inv_resolution_)); }
  int find(const Eigen::Vector3i& coord) const {
    uint32_t slot = hash_voxel(coord) & mask_;
    while (true) {
      const Slot& s = slots_[slot];
      if (s.index < 0) return -1;
      if (s.x == coord.x() && s.y == coord.y() && s.z == coord.z()) return s.index;
      slot = (slot + 1) & mask_;
    }
  }

  const Eigen::Vector3f& mean(int v) const { return means_[v]; }
  const Eigen::Matrix3f& cov(int v) const { return covs_[v]; }
  int count(int v) const { return counts_[v]; }
  Eigen::Vector3i coord(int v) const { return coords_[v]; }

  // The box of the voxels' cells (map frame; empty until finalize()): no point outside it finds a voxel.
  const Eigen::AlignedBox3f& bounds() const { return bounds_; }

  const std::vector<Eigen::Vector3f>& means() const { return means_; }
  const std::vector<Eigen::Matrix3f>& covs() const { return covs_; }
  size_t memory_bytes() const;  // heap held, capacities included

 private:
  struct Slot {
    int32_t x, y, z;
    int32_t index;  // -1: empty
  };
  int find_or_insert(const Eigen::Vector3i& coord);
  void rehash(size_t capacity);
  void drop_empty_voxels();

  double resolution_;
  float inv_resolution_;
  Updates updates_;
  bool finalized_ = false;
  uint32_t mask_ = 0;
  bool has_empty_ = false;
  std::vector<Slot> slots_;
  std::vector<Eigen::Vector3i> coords_;
  std::vector<int> counts_;
  // Accumulators in double: a submap sums thousands of points far from the origin.
  std::vector<Eigen::Vector3d> sum_means_;
  std::vector<Eigen::Matrix3d> sum_covs_;
  std::vector<Eigen::Vector3f> means_;
  std::vector<Eigen::Matrix3f> covs_;
  Eigen::AlignedBox3f bounds_;
};

// Paper Eq. 7-8: fraction of the source points that fall into an occupied target voxel when mapped
// by T_target_source. Asymmetric: overlap(source -> target).
double overlap(const PointCloud& source, const GaussianVoxelMap& target, const Eigen::Isometry3d& T_target_source);

// False only where no point of a source within source_box (its own frame) can fall into a target
// voxel under T_target_source, so that its overlap is 0 without looking up a point. Conservative: the
// boxes are compared with a voxel to spare, for the float rounding of the lookups.
bool may_overlap(const Eigen::AlignedBox3f& source_box, const GaussianVoxelMap& target, const Eigen::Isometry3d& T_target_source);

}  // namespace gcmap
