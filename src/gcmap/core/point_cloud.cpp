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
}  // namespace

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

}  // namespace gcmap
