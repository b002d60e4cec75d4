#include "gcmap/eval/trajectory_metrics.hpp"

#include <Eigen/SVD>
#include <algorithm>
#include <cmath>

#include "gcmap/core/error.hpp"
#include "gcmap/core/se3.hpp"

namespace gcmap {

namespace {

void check_sizes(const Poses& gt, const Poses& est) {
  if (gt.size() != est.size())
    throw Error("trajectories differ in length: " + std::to_string(gt.size()) + " ground-truth vs " + std::to_string(est.size()) +
                " estimated poses");
  if (gt.size() < 2) throw Error("trajectories need at least 2 poses");
}

// As the devkit: acos(clamp(0.5 * (trace - 1))).
double devkit_rotation_error(const Eigen::Isometry3d& E) {
  const double d = 0.5 * (E.linear().trace() - 1.0);
  return std::acos(std::max(std::min(d, 1.0), -1.0));
}

}  // namespace

KittiError kitti_relative_error(const Poses& gt, const Poses& est) {
  check_sizes(gt, est);
  static const double lengths[] = {100, 200, 300, 400, 500, 600, 700, 800};
  std::vector<double> dist(gt.size(), 0.0);
  for (size_t i = 1; i < gt.size(); ++i) dist[i] = dist[i - 1] + (gt[i].translation() - gt[i - 1].translation()).norm();
  KittiError out;
  double t_sum = 0.0, r_sum = 0.0;
  for (double len : lengths) {
    KittiSegmentError seg;
    seg.length = len;
    double ts = 0.0, rs = 0.0;
    for (size_t first = 0; first < gt.size(); first += 10) {
      size_t last = first;
      while (last < gt.size() && !(dist[last] > dist[first] + len)) ++last;
      if (last >= gt.size()) continue;
      const Eigen::Isometry3d delta_gt = gt[first].inverse() * gt[last];
      const Eigen::Isometry3d delta_est = est[first].inverse() * est[last];
      const Eigen::Isometry3d E = delta_est.inverse() * delta_gt;
      const double r = devkit_rotation_error(E) / len, t = E.translation().norm() / len;
      ts += t;
      rs += r;
      ++seg.count;
    }
    if (seg.count) {
      seg.translation_percent = 100.0 * ts / seg.count;
      seg.rotation_deg_per_100m = rs / seg.count * 180.0 / M_PI * 100.0;
      t_sum += ts;
      r_sum += rs;
      out.num_segments += seg.count;
    }
    out.per_length.push_back(seg);
  }
  if (out.num_segments) {
    out.translation_percent = 100.0 * t_sum / out.num_segments;
    out.rotation_deg_per_100m = r_sum / out.num_segments * 180.0 / M_PI * 100.0;
  }
  return out;
}

Eigen::Isometry3d umeyama_se3(const std::vector<Eigen::Vector3d>& a, const std::vector<Eigen::Vector3d>& b) {
  const size_t n = a.size();
  Eigen::Vector3d ma = Eigen::Vector3d::Zero(), mb = Eigen::Vector3d::Zero();
  for (size_t i = 0; i < n; ++i) {
    ma += a[i];
    mb += b[i];
  }
  ma /= n;
  mb /= n;
  Eigen::Matrix3d S = Eigen::Matrix3d::Zero();
  for (size_t i = 0; i < n; ++i) S += (a[i] - ma) * (b[i] - mb).transpose();
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(S, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d D = Eigen::Matrix3d::Identity();
  if ((svd.matrixU() * svd.matrixV().transpose()).determinant() < 0) D(2, 2) = -1;
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = svd.matrixU() * D * svd.matrixV().transpose();
  T.translation() = ma - T.linear() * mb;
  return T;
}

AbsoluteError absolute_trajectory_error(const Poses& gt, const Poses& est) {
  check_sizes(gt, est);
  std::vector<Eigen::Vector3d> a, b;
  for (size_t i = 0; i < gt.size(); ++i) {
    a.push_back(gt[i].translation());
    b.push_back(est[i].translation());
  }
  AbsoluteError out;
  out.T_gt_est = umeyama_se3(a, b);
  double sq = 0.0, sum = 0.0;
  for (size_t i = 0; i < a.size(); ++i) {
    const double e = (a[i] - out.T_gt_est * b[i]).norm();
    sq += e * e;
    sum += e;
    out.max = std::max(out.max, e);
  }
  out.rmse = std::sqrt(sq / a.size());
  out.mean = sum / a.size();
  return out;
}

RelativePoseError relative_pose_error(const Poses& gt, const Poses& est) {
  check_sizes(gt, est);
  RelativePoseError out;
  double tsq = 0, tsum = 0, rsq = 0, rsum = 0;
  const size_t n = gt.size() - 1;
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Isometry3d E = (est[i].inverse() * est[i + 1]).inverse() * (gt[i].inverse() * gt[i + 1]);
    const double t = E.translation().norm(), r = rotation_angle(E) * 180.0 / M_PI;
    tsq += t * t;
    tsum += t;
    rsq += r * r;
    rsum += r;
    out.translation_max = std::max(out.translation_max, t);
    out.rotation_max_deg = std::max(out.rotation_max_deg, r);
  }
  out.translation_rmse = std::sqrt(tsq / n);
  out.translation_mean = tsum / n;
  out.rotation_rmse_deg = std::sqrt(rsq / n);
  out.rotation_mean_deg = rsum / n;
  return out;
}

VerticalError vertical_error(const Poses& gt, const Poses& est) {
  if (gt.size() != est.size()) throw Error("vertical_error: trajectories differ in length");
  VerticalError e;
  double sum = 0.0;
  for (size_t i = 0; i < gt.size(); ++i) {
    const Eigen::Vector3d a = gt[i].linear().transpose() * Eigen::Vector3d::UnitZ();
    const Eigen::Vector3d b = est[i].linear().transpose() * Eigen::Vector3d::UnitZ();
    const double deg = std::atan2(a.cross(b).norm(), a.dot(b)) * 180.0 / M_PI;
    sum += deg * deg;
    e.mean_deg += deg / double(gt.size());
    e.max_deg = std::max(e.max_deg, deg);
  }
  if (!gt.empty()) e.rmse_deg = std::sqrt(sum / double(gt.size()));
  return e;
}

}  // namespace gcmap
