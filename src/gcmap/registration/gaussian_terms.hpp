#pragma once
// Per-point terms shared by VGICP (target = voxel map) and GICP (target = point cloud): a source
// point i associated to target element v gives e = mu_v - T p_i, Omega = (C_v + R C_i R^T)^-1. The
// sums are accumulated in the target frame (see vgicp.hpp, TargetFrameSums).
#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include "gcmap/core/gaussian_voxel_map.hpp"
#include "gcmap/core/point_cloud.hpp"
#include "gcmap/registration/vgicp.hpp"

namespace gcmap::detail {

// Target traits: the Gaussian of element v.
inline const Eigen::Vector3f& target_mean(const GaussianVoxelMap& t, int v) { return t.mean(v); }
inline const Eigen::Matrix3f& target_cov(const GaussianVoxelMap& t, int v) { return t.cov(v); }
inline const Eigen::Vector3f& target_mean(const PointCloud& t, int v) { return t.points[v]; }
inline const Eigen::Matrix3f& target_cov(const PointCloud& t, int v) { return t.covs[v]; }

constexpr size_t kGrain = 512;

struct PointTerms {
  Eigen::Vector3f q, e;
  Eigen::Matrix3f omega;
};

// Residual and weight of the transformed point out.q against element v; false when there is no
// correspondence (v < 0) or the fused covariance is degenerate.
template <class Target>
inline bool point_terms(const PointCloud& source, const Target& target, const Eigen::Matrix3f& R, size_t i, int v,
                        PointTerms& out) {
  if (v < 0) return false;
  const Eigen::Matrix3f S = target_cov(target, v) + R * source.covs[i] * R.transpose();
  bool invertible = false;
  float det = 0.f;
  S.computeInverseAndDetWithCheck(out.omega, det, invertible, 1e-12f);
  if (!invertible) return false;
  out.e = target_mean(target, v) - out.q;
  return true;
}

// associate(i, q) -> target element of source point i (transformed to q), or -1.
// Float within a chunk of <= kGrain points; chunks are summed in double in a fixed order.
template <class Target, class Associate>
TargetFrameSums accumulate_target_frame(const PointCloud& source, const Target& target, const Eigen::Isometry3d& T,
                                        Associate associate) {
  const PointTransform X(T);
  return tbb::parallel_deterministic_reduce(
      tbb::blocked_range<size_t>(0, source.size(), kGrain), TargetFrameSums{},
      [&](const tbb::blocked_range<size_t>& r, TargetFrameSums acc) {
        Eigen::Matrix<float, 6, 6> H = Eigen::Matrix<float, 6, 6>::Zero();
        Eigen::Matrix<float, 6, 1> b = Eigen::Matrix<float, 6, 1>::Zero();
        double error = 0.0;
        size_t inliers = 0;
        PointTerms p;
        for (size_t i = r.begin(); i != r.end(); ++i) {
          p.q = X * source.points[i];
          if (!point_terms(source, target, X.R, i, associate(i, p.q), p)) continue;
          // B = [-Q, I] with Q = [q]x: B^T W B = [[-Q W Q, Q W], [-W Q, W]], B^T W e = [Q W e; W e].
          const Eigen::Matrix3f Q = skew(p.q);
          const Eigen::Matrix3f QW = Q * p.omega;
          H.block<3, 3>(0, 0).noalias() -= QW * Q;
          H.block<3, 3>(0, 3) += QW;
          H.block<3, 3>(3, 3) += p.omega;
          const Eigen::Vector3f We = p.omega * p.e;
          b.head<3>().noalias() += Q * We;
          b.tail<3>() += We;
          error += p.e.dot(We);
          ++inliers;
        }
        H.block<3, 3>(3, 0) = H.block<3, 3>(0, 3).transpose();
        acc.H += H.cast<double>();
        acc.b += b.cast<double>();
        acc.error += error;
        acc.num_inliers += inliers;
        return acc;
      },
      [](TargetFrameSums a, const TargetFrameSums& b) {
        a.H += b.H;
        a.b += b.b;
        a.error += b.error;
        a.num_inliers += b.num_inliers;
        return a;
      });
}

template <class Target, class Associate>
VgicpError sum_errors(const PointCloud& source, const Target& target, const Eigen::Isometry3d& T, Associate associate) {
  const PointTransform X(T);
  using Pair = std::pair<double, size_t>;
  const Pair sum = tbb::parallel_deterministic_reduce(
      tbb::blocked_range<size_t>(0, source.size(), kGrain), Pair{0.0, 0},
      [&](const tbb::blocked_range<size_t>& r, Pair acc) {
        PointTerms p;
        for (size_t i = r.begin(); i != r.end(); ++i) {
          p.q = X * source.points[i];
          if (!point_terms(source, target, X.R, i, associate(i, p.q), p)) continue;
          acc.first += p.e.dot(p.omega * p.e);
          ++acc.second;
        }
        return acc;
      },
      [](Pair a, const Pair& b) { return Pair{a.first + b.first, a.second + b.second}; });
  return {sum.first, sum.second};
}

}  // namespace gcmap::detail
