#include "gcmap/registration/vgicp.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

namespace gcmap {

namespace {

constexpr size_t kGrain = 512;

struct PointTerms {
  Eigen::Vector3f q, e;
  Eigen::Matrix3f omega;
};

// Residual and weight of the transformed point out.q against voxel v; false when there is no voxel
// or the fused covariance is degenerate.
inline bool voxel_terms(const PointCloud& source, const GaussianVoxelMap& target, const Eigen::Matrix3f& R, size_t i,
                        int v, PointTerms& out) {
  if (v < 0) return false;
  const Eigen::Matrix3f S = target.cov(v) + R * source.covs[i] * R.transpose();
  bool invertible = false;
  float det = 0.f;
  S.computeInverseAndDetWithCheck(out.omega, det, invertible, 1e-12f);
  if (!invertible) return false;
  out.e = target.mean(v) - out.q;
  return true;
}

struct Transform {
  Eigen::Matrix3f R;
  Eigen::Vector3f t;
  explicit Transform(const Eigen::Isometry3d& T) : R(T.linear().cast<float>()), t(T.translation().cast<float>()) {}
  Eigen::Vector3f operator*(const Eigen::Vector3f& p) const { return R * p + t; }
};

TargetFrameSums accumulate(const PointCloud& source, const GaussianVoxelMap& target, const Eigen::Isometry3d& T) {
  const Transform X(T);
  return tbb::parallel_deterministic_reduce(
      tbb::blocked_range<size_t>(0, source.size(), kGrain), TargetFrameSums{},
      [&](const tbb::blocked_range<size_t>& r, TargetFrameSums acc) {
        // Float within a chunk of <= kGrain points; chunks are summed in double.
        Eigen::Matrix<float, 6, 6> H = Eigen::Matrix<float, 6, 6>::Zero();
        Eigen::Matrix<float, 6, 1> b = Eigen::Matrix<float, 6, 1>::Zero();
        double error = 0.0;
        size_t inliers = 0;
        PointTerms p;
        for (size_t i = r.begin(); i != r.end(); ++i) {
          p.q = X * source.points[i];
          if (!voxel_terms(source, target, X.R, i, target.lookup(p.q), p)) continue;
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

template <typename Associate>
VgicpError sum_errors(const PointCloud& source, const GaussianVoxelMap& target, const Transform& X, Associate associate) {
  using Pair = std::pair<double, size_t>;
  const Pair sum = tbb::parallel_deterministic_reduce(
      tbb::blocked_range<size_t>(0, source.size(), kGrain), Pair{0.0, 0},
      [&](const tbb::blocked_range<size_t>& r, Pair acc) {
        PointTerms p;
        for (size_t i = r.begin(); i != r.end(); ++i) {
          p.q = X * source.points[i];
          if (!voxel_terms(source, target, X.R, i, associate(i, p.q), p)) continue;
          acc.first += p.e.dot(p.omega * p.e);
          ++acc.second;
        }
        return acc;
      },
      [](Pair a, const Pair& b) { return Pair{a.first + b.first, a.second + b.second}; });
  return {sum.first, sum.second};
}

}  // namespace

VgicpLinearization expand_to_both_poses(const TargetFrameSums& sums, const Eigen::Isometry3d& T) {
  const Matrix6d M = adjoint(T);
  VgicpLinearization out;
  out.H_jj = sums.H;
  out.b_j = sums.b;
  out.H_ij = -M.transpose() * sums.H;
  out.H_ii = -out.H_ij * M;
  out.b_i = -M.transpose() * sums.b;
  out.error = sums.error;
  out.num_inliers = sums.num_inliers;
  return out;
}

VgicpLinearization linearize_vgicp(const PointCloud& source, const GaussianVoxelMap& target,
                                   const Eigen::Isometry3d& T_target_source) {
  return expand_to_both_poses(accumulate(source, target, T_target_source), T_target_source);
}

VgicpError evaluate_vgicp(const PointCloud& source, const GaussianVoxelMap& target,
                          const Eigen::Isometry3d& T_target_source) {
  return sum_errors(source, target, Transform(T_target_source),
                    [&](size_t, const Eigen::Vector3f& q) { return target.lookup(q); });
}

VgicpError evaluate_vgicp(const PointCloud& source, const GaussianVoxelMap& target,
                          const Eigen::Isometry3d& T_target_source, const Eigen::Isometry3d& T_association) {
  const Transform A(T_association);
  return sum_errors(source, target, Transform(T_target_source),
                    [&](size_t i, const Eigen::Vector3f&) { return target.lookup(A * source.points[i]); });
}

}  // namespace gcmap
