#include "gcmap/core/point_cloud.hpp"

namespace gcmap {

namespace {
template <typename T>
void filter_channel(std::vector<T>& v, const std::vector<char>& keep) {
  if (v.empty()) return;
  size_t out = 0;
  for (size_t i = 0; i < v.size(); ++i) {
    if (keep[i]) v[out++] = v[i];
  }
  v.resize(out);
}

template <typename T>
void select_channel(const std::vector<T>& in, const std::vector<char>& keep, size_t count, std::vector<T>& out) {
  if (in.empty()) return;
  out.reserve(count);
  for (size_t i = 0; i < in.size(); ++i) {
    if (keep[i]) out.push_back(in[i]);
  }
}
}  // namespace

PointCloud PointCloud::selected(const std::vector<char>& keep) const {
  size_t count = 0;
  for (size_t i = 0; i < size(); ++i) count += keep[i] != 0;
  PointCloud out;
  select_channel(points, keep, count, out.points);
  select_channel(covs, keep, count, out.covs);
  select_channel(intensities, keep, count, out.intensities);
  select_channel(times, keep, count, out.times);
  select_channel(labels, keep, count, out.labels);
  return out;
}

void PointCloud::filter(const std::vector<char>& keep) {
  filter_channel(points, keep);
  filter_channel(covs, keep);
  filter_channel(intensities, keep);
  filter_channel(times, keep);
  filter_channel(labels, keep);
}

PointCloud transformed(const PointCloud& cloud, const Eigen::Isometry3d& T) {
  PointCloud out = cloud;
  const Eigen::Matrix3f R = T.linear().cast<float>();
  const Eigen::Vector3f t = T.translation().cast<float>();
  for (auto& p : out.points) p = R * p + t;
  for (auto& c : out.covs) c = R * c * R.transpose();
  return out;
}

Eigen::AlignedBox3f bounding_box(const PointCloud& cloud) {
  Eigen::AlignedBox3f box;  // empty
  for (const Eigen::Vector3f& p : cloud.points) box.extend(p);
  return box;
}

}  // namespace gcmap
