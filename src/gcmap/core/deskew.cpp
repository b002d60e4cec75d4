#include "gcmap/core/deskew.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "gcmap/core/error.hpp"

namespace gcmap {

void deskew(PointCloud& cloud, const Vector6d& velocity) { deskew(cloud, velocity, Vector6d::Zero()); }

namespace {

// The sensor poses T_0_t at times t0 + k step, k = 0 .. n: a point between two of them takes the
// linear blend of their rotations and translations. At a step of at most 5e-4 rad this is within
// 3 um of the exact pose at 100 m; per point it replaces an exponential map (downsampled sweeps
// have as many distinct times as points, and each sweep is deskewed five times or more).
struct PoseTable {
  float t0 = 0.f, inv_step = 0.f;
  std::vector<Eigen::Matrix3f> R;
  std::vector<Eigen::Vector3f> t;
  void at(float time, Eigen::Matrix3f& Ri, Eigen::Vector3f& ti) const {
    const float f = (time - t0) * inv_step;  // NaN (a NaN time) takes the first pose
    const float x = f >= 0.f ? std::min(f, static_cast<float>(R.size() - 1)) : 0.f;
    const size_t k = std::min(static_cast<size_t>(x), R.size() - 2);
    const float w = x - static_cast<float>(k);
    Ri = (1.f - w) * R[k] + w * R[k + 1];
    ti = (1.f - w) * t[k] + w * t[k + 1];
  }
};

constexpr double kMaxTableStep = 5e-4;  // rad between neighbouring poses of the table

// Each point moved by pose(time, R, t), its sensor pose T_0_time; covariances rotated with it.
template <typename PoseOf>
void move_points(PointCloud& cloud, const PoseOf& pose) {
  const bool covs = cloud.has_covs();
  tbb::parallel_for(tbb::blocked_range<size_t>(0, cloud.size(), 4096), [&](const tbb::blocked_range<size_t>& r) {
    // Drivers write many points with one time (a column of a spinning sensor): reuse its pose.
    float last_t = std::nanf("");
    Eigen::Matrix3f R = Eigen::Matrix3f::Identity();
    Eigen::Vector3f t = Eigen::Vector3f::Zero();
    for (size_t i = r.begin(); i != r.end(); ++i) {
      if (cloud.times[i] != last_t) {
        last_t = cloud.times[i];
        pose(last_t, R, t);
      }
      cloud.points[i] = R * cloud.points[i] + t;
      if (covs) cloud.covs[i] = R * cloud.covs[i] * R.transpose();
    }
  });
}

}  // namespace

void deskew(PointCloud& cloud, const Vector6d& velocity, const Vector6d& acceleration, double anchor) {
  if (!cloud.has_times()) return;
  if (cloud.times.size() != cloud.size()) throw Error("deskew: times and points differ in number");
  if (!velocity.allFinite() || !acceleration.allFinite() || !std::isfinite(anchor)) throw Error("deskew: non-finite velocity");
  const auto T_anchor = [&](double t) {
    const double u = t - anchor;
    return se3_exp(u * velocity + 0.5 * u * u * acceleration);
  };
  const Eigen::Isometry3d T_0_anchor = T_anchor(0.0).inverse();
  const auto T_0 = [&](double t) { return T_0_anchor * T_anchor(t); };
  const auto [lo, hi] = std::minmax_element(cloud.times.begin(), cloud.times.end());
  // A bound on the rotation over the sweep (anchor outside it included) sizes the table.
  const double span = static_cast<double>(*hi) - *lo;
  const double reach = std::max({std::abs(*lo - anchor), std::abs(*hi - anchor), span});
  const double turn = span * (velocity.head<3>().norm() + reach * acceleration.head<3>().norm());
  // At most a quarter as many poses as points: bad times (absolute stamps, a huge span) cannot
  // make the table large, they leave the exponential map per time.
  const double steps_wanted = std::ceil(turn / kMaxTableStep) + 16.0;
  const bool tabled = span > 0.0 && 4.0 * steps_wanted < static_cast<double>(cloud.size());
  const size_t steps = tabled ? static_cast<size_t>(steps_wanted) : 0;
  PoseTable table;
  if (tabled) {
    table.t0 = *lo;
    table.inv_step = static_cast<float>(steps / span);
    for (size_t k = 0; k <= steps; ++k) {
      const Eigen::Isometry3d T = T_0(*lo + span * static_cast<double>(k) / static_cast<double>(steps));
      table.R.push_back(T.linear().cast<float>());
      table.t.push_back(T.translation().cast<float>());
    }
  }
  move_points(cloud, [&](float time, Eigen::Matrix3f& R, Eigen::Vector3f& t) {
    if (tabled) return table.at(time, R, t);
    const Eigen::Isometry3d T_0_t = T_0(time);
    R = T_0_t.linear().cast<float>();
    t = T_0_t.translation().cast<float>();
  });
}

Eigen::Isometry3d SweepPoses::at(double t) const {
  if (T.empty()) throw Error("SweepPoses: no poses");
  const double x = std::clamp((t - t0) / step, 0.0, static_cast<double>(T.size() - 1));
  const size_t k = std::min(static_cast<size_t>(x), T.size() - (T.size() > 1 ? 2 : 1));
  const double w = x - static_cast<double>(k);
  if (T.size() == 1 || w == 0.0) return T[k];
  Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
  out.linear() = (1.0 - w) * T[k].linear() + w * T[k + 1].linear();
  out.translation() = (1.0 - w) * T[k].translation() + w * T[k + 1].translation();
  return out;
}

void deskew(PointCloud& cloud, const SweepPoses& poses) {
  if (!cloud.has_times()) return;
  if (cloud.times.size() != cloud.size()) throw Error("deskew: times and points differ in number");
  if (poses.T.size() < 2 || !(poses.step > 0)) throw Error("deskew: a pose table needs two poses and a positive step");
  PoseTable table;
  table.t0 = static_cast<float>(poses.t0);
  table.inv_step = static_cast<float>(1.0 / poses.step);
  for (const Eigen::Isometry3d& T : poses.T) {
    table.R.push_back(T.linear().cast<float>());
    table.t.push_back(T.translation().cast<float>());
  }
  move_points(cloud, [&](float time, Eigen::Matrix3f& R, Eigen::Vector3f& t) { table.at(time, R, t); });
}

void deskew(PointCloud& cloud, const Eigen::Isometry3d& T_begin_end, double sweep_duration) {
  if (!(sweep_duration > 0) || !std::isfinite(sweep_duration)) throw Error("deskew: sweep duration must be > 0");
  deskew(cloud, Vector6d(se3_log(T_begin_end) / sweep_duration));
}

}  // namespace gcmap
