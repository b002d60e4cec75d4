#pragma once
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <vector>

namespace gcmap {

// Structure of arrays: the registration hot loops touch only points and covs.
// Optional channels are either empty or of size().
struct PointCloud {
  std::vector<Eigen::Vector3f> points;
  std::vector<Eigen::Matrix3f> covs;
  std::vector<float> intensities;
  std::vector<float> times;
  std::vector<uint32_t> labels;

  size_t size() const { return points.size(); }
  bool empty() const { return points.empty(); }
  bool has_covs() const { return !covs.empty() && covs.size() == points.size(); }
  bool has_intensities() const { return !intensities.empty(); }
  bool has_times() const { return !times.empty(); }
  bool has_labels() const { return !labels.empty(); }

  size_t memory_bytes() const {  // heap held, capacities included
    return points.capacity() * sizeof(Eigen::Vector3f) + covs.capacity() * sizeof(Eigen::Matrix3f) +
           (intensities.capacity() + times.capacity()) * sizeof(float) + labels.capacity() * sizeof(uint32_t);
  }

  // Keeps the points whose flag is true, in order, for every channel present.
  void filter(const std::vector<char>& keep);
  // The same as a copy, without copying what is dropped.
  PointCloud selected(const std::vector<char>& keep) const;
};

// Returns the cloud with every point (and covariance) mapped by T.
PointCloud transformed(const PointCloud& cloud, const Eigen::Isometry3d& T);

// The smallest axis-aligned box holding every point (empty for an empty cloud).
Eigen::AlignedBox3f bounding_box(const PointCloud& cloud);

}  // namespace gcmap
