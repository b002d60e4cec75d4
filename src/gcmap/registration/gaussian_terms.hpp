#pragma once
// Per-point terms shared by VGICP (target = voxel map) and GICP (target = point cloud): a source
// point i associated to target element v gives e = mu_v - T p_i, Omega = (C_v + R C_i R^T)^-1. The
// sums are accumulated in the target frame (see vgicp.hpp, TargetFrameSums).
//
// Two stages per batch of points: a scalar pass transforms, associates and gathers the associated
// points' Gaussians into structure-of-arrays form; the arithmetic then runs kLanes points at a time
// on GCC vector types (SSE, NEON, whatever the target has), with symmetric 3x3 algebra written
// out. Sums are float within a chunk of <= kGrain points and double across chunks, in a fixed
// order: the same result for any thread count.
#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include <cmath>

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
constexpr int kLanes = 4;
using Lanes = float __attribute__((vector_size(kLanes * sizeof(float))));
using LaneMask = int __attribute__((vector_size(kLanes * sizeof(int))));

// Upper triangle of a symmetric 3x3 matrix: 00 01 02 11 12 22.
constexpr int kSym[3][3] = {{0, 1, 2}, {1, 3, 4}, {2, 4, 5}};

// The associated points of one batch, structure of arrays. Unused lanes of the last group have
// zero covariances: their fused covariance is singular and they drop out like degenerate points.
struct Gathered {
  static constexpr int kCapacity = 128;
  alignas(32) float q[3][kCapacity];     // source point in the target frame
  alignas(32) float mean[3][kCapacity];  // target Gaussian
  alignas(32) float target[6][kCapacity];
  alignas(32) float source[6][kCapacity];  // source covariance, source frame
  int size = 0;

  void push(const Eigen::Vector3f& qi, const Eigen::Vector3f& mu, const Eigen::Matrix3f& Ct, const Eigen::Matrix3f& Cs) {
    for (int a = 0; a < 3; ++a) {
      q[a][size] = qi[a];
      mean[a][size] = mu[a];
      for (int c = a; c < 3; ++c) {
        target[kSym[a][c]][size] = Ct(a, c);
        source[kSym[a][c]][size] = Cs(a, c);
      }
    }
    ++size;
  }
  // Zero-pads to a whole number of lane groups; returns the number of groups.
  int close() {
    const int groups = (size + kLanes - 1) / kLanes;
    for (int k = size; k < groups * kLanes; ++k) {
      for (int a = 0; a < 3; ++a) q[a][k] = mean[a][k] = 0.f;
      for (int s = 0; s < 6; ++s) target[s][k] = source[s][k] = 0.f;
    }
    return groups;
  }
};

inline Lanes load(const float* p) {
  Lanes v;
  __builtin_memcpy(&v, p, sizeof(v));
  return v;
}

// kLanes points of a batch: residual e, Omega (upper triangle) and which lanes count; with a robust
// width, each point's cost too.
struct LaneTerms {
  Lanes q[3], e[3], W[6];
  Lanes cost;
  LaneMask valid;
};

inline Lanes squared_mahalanobis(const Lanes (&W)[6], const Lanes (&e)[3]) {
  return W[0] * e[0] * e[0] + W[3] * e[1] * e[1] + W[5] * e[2] * e[2] +
         2.f * (W[1] * e[0] * e[1] + W[2] * e[0] * e[2] + W[4] * e[1] * e[2]);
}

// Omega = (C_target + R C_source R^T)^-1 by cofactors; lanes whose determinant is not above 1e-12
// get Omega = 0 (as Eigen's invertibility check did for the scalar code this replaced). With a
// robust width c (c2 = c^2 > 0) the cost is Cauchy's, c2 log(1 + m2 / c2) with m2 = e^T Omega e,
// and Omega is scaled by its IRLS weight c2 / (c2 + m2): b stays half the cost's gradient.
inline void lane_terms(const Gathered& g, int group, const float (&R)[3][3], float c2, LaneTerms& t) {
  const int o = group * kLanes;
  Lanes C[6], S[6];
  for (int s = 0; s < 6; ++s) C[s] = load(g.source[s] + o);
  for (int a = 0; a < 3; ++a) {
    t.q[a] = load(g.q[a] + o);
    t.e[a] = load(g.mean[a] + o) - t.q[a];
  }
  // RC = R C (full), S = RC R^T + C_target (upper triangle).
  Lanes RC[3][3];
  for (int a = 0; a < 3; ++a)
    for (int c = 0; c < 3; ++c) RC[a][c] = R[a][0] * C[kSym[0][c]] + R[a][1] * C[kSym[1][c]] + R[a][2] * C[kSym[2][c]];
  for (int a = 0; a < 3; ++a)
    for (int c = a; c < 3; ++c)
      S[kSym[a][c]] = load(g.target[kSym[a][c]] + o) + RC[a][0] * R[c][0] + RC[a][1] * R[c][1] + RC[a][2] * R[c][2];
  const Lanes a00 = S[0], a01 = S[1], a02 = S[2], a11 = S[3], a12 = S[4], a22 = S[5];
  const Lanes c00 = a11 * a22 - a12 * a12, c01 = a02 * a12 - a01 * a22, c02 = a01 * a12 - a02 * a11;
  const Lanes det = a00 * c00 + a01 * c01 + a02 * c02;
  t.valid = (det > 1e-12f) | (det < -1e-12f);
  const Lanes zero = {};
  const Lanes safe_det = t.valid ? det : zero + 1.f;
  const Lanes inv = t.valid ? 1.f / safe_det : zero;
  t.W[0] = c00 * inv;
  t.W[1] = c01 * inv;
  t.W[2] = c02 * inv;
  t.W[3] = (a00 * a22 - a02 * a02) * inv;
  t.W[4] = (a01 * a02 - a00 * a12) * inv;
  t.W[5] = (a00 * a11 - a01 * a01) * inv;
  if (c2 > 0.f) {
    const Lanes m2 = squared_mahalanobis(t.W, t.e);
    const Lanes w = c2 / (c2 + m2);
    for (int s = 0; s < 6; ++s) t.W[s] *= w;
    for (int l = 0; l < kLanes; ++l) t.cost[l] = c2 * std::log1p(m2[l] / c2);
  } else {
    t.cost = zero;  // unread
  }
}

inline double horizontal_sum(const Lanes& v) {
  double s = 0.0;
  for (int l = 0; l < kLanes; ++l) s += v[l];
  return s;
}
inline size_t count(const LaneMask& m) {
  size_t n = 0;
  for (int l = 0; l < kLanes; ++l) n += m[l] != 0;
  return n;
}

// Gathers source point i if it has a correspondence (associate(i, q) >= 0).
template <class Target, class Associate>
inline auto gatherer(const PointCloud& source, const Target& target, const PointTransform& X, Associate& associate) {
  return [&source, &target, &X, &associate](size_t i, Gathered& g) {
    const Eigen::Vector3f q = X * source.points[i];
    const int v = associate(i, q);
    if (v >= 0) g.push(q, target_mean(target, v), target_cov(target, v), source.covs[i]);
  };
}

inline void rotation_rows(const PointTransform& X, float (&R)[3][3]) {
  for (int a = 0; a < 3; ++a)
    for (int c = 0; c < 3; ++c) R[a][c] = X.R(a, c);
}

// Gathers source points [begin, end) batch by batch and runs body(terms, err) on every group of
// kLanes associated points; body adds the groups' errors to err, which is summed in double per
// batch. Returns that sum.
template <class Gather, class Body>
inline double for_each_lane_group(size_t begin, size_t end, Gather gather, const float (&R)[3][3], float c2, Body body) {
  Gathered g;
  double error = 0.0;
  const auto run = [&] {
    const int groups = g.close();
    Lanes err = {};
    for (int k = 0; k < groups; ++k) {
      LaneTerms t;
      lane_terms(g, k, R, c2, t);
      body(t, err);
    }
    error += horizontal_sum(err);
    g.size = 0;
  };
  for (size_t i = begin; i != end; ++i) {
    gather(i, g);
    if (g.size == Gathered::kCapacity) run();
  }
  if (g.size) run();
  return error;
}

// associate(i, q) -> target element of source point i (transformed to q), or -1; c2: the robust
// width squared (0: none).
template <class Target, class Associate>
TargetFrameSums accumulate_target_frame(const PointCloud& source, const Target& target, const Eigen::Isometry3d& T,
                                        Associate associate, float c2 = 0.f) {
  const PointTransform X(T);
  float R[3][3];
  rotation_rows(X, R);
  return tbb::parallel_deterministic_reduce(
      tbb::blocked_range<size_t>(0, source.size(), kGrain), TargetFrameSums{},
      [&](const tbb::blocked_range<size_t>& r, TargetFrameSums acc) {
        // Target-frame Jacobian B = [-Q, I], Q = [q]x: B^T W B = [[-Q W Q, Q W], [-W Q, W]],
        // B^T W e = [Q W e; W e]. Sums: Hrr (upper), Hrt (full), Htt (upper), br, bt, error.
        Lanes Hrr[6] = {}, Hrt[9] = {}, Htt[6] = {}, br[3] = {}, bt[3] = {};
        size_t inliers = 0;
        const auto add_terms = [&](const LaneTerms& t, Lanes& err) {
          const Lanes(&W)[6] = t.W;
          const Lanes &qx = t.q[0], &qy = t.q[1], &qz = t.q[2];
          const Lanes We[3] = {W[0] * t.e[0] + W[1] * t.e[1] + W[2] * t.e[2], W[1] * t.e[0] + W[3] * t.e[1] + W[4] * t.e[2],
                               W[2] * t.e[0] + W[4] * t.e[1] + W[5] * t.e[2]};
          err += c2 > 0.f ? t.cost : t.e[0] * We[0] + t.e[1] * We[1] + t.e[2] * We[2];
          // QW, row by row (W symmetric).
          Lanes QW[3][3];
          for (int c = 0; c < 3; ++c) {
            QW[0][c] = qy * W[kSym[2][c]] - qz * W[kSym[1][c]];
            QW[1][c] = qz * W[kSym[0][c]] - qx * W[kSym[2][c]];
            QW[2][c] = qx * W[kSym[1][c]] - qy * W[kSym[0][c]];
          }
          for (int a = 0; a < 3; ++a) {
            // (QW Q)(a, c) for c >= a; Q's columns are (0, qz, -qy), (-qz, 0, qx), (qy, -qx, 0).
            const Lanes P[3] = {QW[a][1] * qz - QW[a][2] * qy, QW[a][2] * qx - QW[a][0] * qz, QW[a][0] * qy - QW[a][1] * qx};
            for (int c = a; c < 3; ++c) Hrr[kSym[a][c]] -= P[c];
            for (int c = 0; c < 3; ++c) Hrt[a * 3 + c] += QW[a][c];
          }
          for (int s = 0; s < 6; ++s) Htt[s] += W[s];
          br[0] += qy * We[2] - qz * We[1];
          br[1] += qz * We[0] - qx * We[2];
          br[2] += qx * We[1] - qy * We[0];
          for (int a = 0; a < 3; ++a) bt[a] += We[a];
          inliers += count(t.valid);
        };
        const double error = for_each_lane_group(r.begin(), r.end(), gatherer(source, target, X, associate), R, c2, add_terms);
        for (int a = 0; a < 3; ++a) {
          for (int c = 0; c < 3; ++c) {
            const double rt = horizontal_sum(Hrt[a * 3 + c]);
            acc.H(a, 3 + c) += rt;
            acc.H(3 + c, a) += rt;
            if (c < a) continue;
            const double rr = horizontal_sum(Hrr[kSym[a][c]]), tt = horizontal_sum(Htt[kSym[a][c]]);
            acc.H(a, c) += rr;
            acc.H(3 + a, 3 + c) += tt;
            if (c == a) continue;
            acc.H(c, a) += rr;
            acc.H(3 + c, 3 + a) += tt;
          }
          acc.b[a] += horizontal_sum(br[a]);
          acc.b[3 + a] += horizontal_sum(bt[a]);
        }
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
VgicpError sum_errors(const PointCloud& source, const Target& target, const Eigen::Isometry3d& T, Associate associate,
                      float c2 = 0.f) {
  const PointTransform X(T);
  float R[3][3];
  rotation_rows(X, R);
  using Pair = std::pair<double, size_t>;
  const Pair sum = tbb::parallel_deterministic_reduce(
      tbb::blocked_range<size_t>(0, source.size(), kGrain), Pair{0.0, 0},
      [&](const tbb::blocked_range<size_t>& r, Pair acc) {
        const auto add_error = [&](const LaneTerms& t, Lanes& err) {
          err += c2 > 0.f ? t.cost : squared_mahalanobis(t.W, t.e);
          acc.second += count(t.valid);
        };
        acc.first += for_each_lane_group(r.begin(), r.end(), gatherer(source, target, X, associate), R, c2, add_error);
        return acc;
      },
      [](Pair a, const Pair& b) {
        return Pair{a.first + b.first, a.second + b.second};
      });
  return {sum.first, sum.second};
}

}  // namespace gcmap::detail
