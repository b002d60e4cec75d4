#include "gcmap/core/deskew.hpp"

#include <tbb/parallel_for.h>

#include <cmath>

#include "gcmap/core/error.hpp"

namespace gcmap {

void deskew(PointCloud& cloud, const Vector6d& velocity) { deskew(cloud, velocity, Vector6d::Zero()); }

void deskew(PointCloud& cloud, const Vector6d& velocity, const Vector6d& acceleration, double anchor) {
  if (!cloud.has_times()) return;
  if (cloud.times.size() != cloud.size()) throw Error("deskew: times and points differ in number");
  if (!velocity.allFinite() || !acceleration.allFinite() || !std::isfinite(anchor))
    throw Error("deskew: non-finite velocity");
  const bool covs = cloud.has_covs();
  const auto T_anchor = [&](double t) {
    const double u = t - anchor;
    return se3_exp(u * velocity + 0.5 * u * u * acceleration);
  };
  const Eigen::Isometry3d T_0_anchor = T_anchor(0.0).inverse();
  tbb::parallel_for(tbb::blocked_range<size_t>(0, cloud.size(), 4096), [&](const tbb::blocked_range<size_t>& r) {
    // Drivers write many points with one time (a column of a spinning sensor): reuse its pose.
    float last_t = std::nanf("");
    Eigen::Matrix3f R = Eigen::Matrix3f::Identity();
    Eigen::Vector3f t = Eigen::Vector3f::Zero();
    for (size_t i = r.begin(); i != r.end(); ++i) {
      if (cloud.times[i] != last_t) {
        last_t = cloud.times[i];
        const Eigen::Isometry3d T_0_t = T_0_anchor * T_anchor(last_t);
        R = T_0_t.linear().cast<float>();
        t = T_0_t.translation().cast<float>();
      }
      cloud.points[i] = R * cloud.points[i] + t;
      if (covs) cloud.covs[i] = R * cloud.covs[i] * R.transpose();
    }
  });
}

void deskew(PointCloud& cloud, const Eigen::Isometry3d& T_begin_end, double sweep_duration) {
  if (!(sweep_duration > 0) || !std::isfinite(sweep_duration)) throw Error("deskew: sweep duration must be > 0");
  deskew(cloud, Vector6d(se3_log(T_begin_end) / sweep_duration));
}

}  // namespace gcmap
