#include "gcmap/graph/rotation_smoother.hpp"

#include <algorithm>
#include <cmath>

namespace gcmap {
namespace {

using Eigen::Matrix3d;
using Eigen::Vector3d;

constexpr double kChi2OneMedian = 0.4549;  // median of a squared unit normal
constexpr size_t kMinWindows = 20;
constexpr int kIterations = 3;

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

Matrix3d right_jacobian_inverse(const Vector3d& r) { return so3_left_jacobian_inverse(-r); }

// The gyro's rotation over frames first+1..last, when it spans them all.
std::optional<GyroRotation> chain(const std::vector<std::optional<GyroRotation>>& gyro, size_t first, size_t last) {
  GyroRotation c;
  for (size_t j = first + 1; j <= last; ++j) {
    if (!gyro[j]) return std::nullopt;
    c = c.then(*gyro[j]);
  }
  return c;
}

// Per-axis variances, robustly (medians: a failed frame must not decide): the disagreement of the
// trajectory with the gyro over windows of kRotationNoiseSpan frames, and the gyro's own over such
// a window and between consecutive frames.
RotationSmoothing measure(const std::vector<Eigen::Isometry3d>& poses, const std::vector<std::optional<GyroRotation>>& gyro) {
  std::vector<double> squares, window_variances, step_variances;
  for (size_t k = 1; k < gyro.size(); ++k)
    if (gyro[k]) step_variances.push_back(gyro[k]->variance);
  for (size_t k = 0; k + kRotationNoiseSpan < poses.size(); k += kRotationNoiseSpan) {
    const auto c = chain(gyro, k, k + kRotationNoiseSpan);
    if (!c) continue;
    const Vector3d e = so3_log(c->R.transpose() * poses[k].linear().transpose() * poses[k + kRotationNoiseSpan].linear());
    for (int a = 0; a < 3; ++a) squares.push_back(e[a] * e[a]);
    window_variances.push_back(c->variance);
  }
  RotationSmoothing s;
  s.windows = window_variances.size();
  const double frame_variance = (median(squares) / kChi2OneMedian - median(window_variances)) / 2.0;
  const double step_variance = median(step_variances);
  s.frame_noise_deg = frame_variance > 0.0 ? std::sqrt(frame_variance) * 180.0 / M_PI : 0.0;
  s.gyro_noise_deg = std::sqrt(step_variance) * 180.0 / M_PI;
  s.applied = s.windows >= kMinWindows && frame_variance > step_variance;
  return s;
}

// H dx = -b for H block tridiagonal: D on the diagonal, B[k] = H(k-1, k) (B[0] unused).
std::vector<Vector3d> solve_tridiagonal(const std::vector<Matrix3d>& D, const std::vector<Matrix3d>& B,
                                        const std::vector<Vector3d>& b) {
  const size_t n = D.size();
  std::vector<Matrix3d> S_inv(n);
  std::vector<Vector3d> y(n), x(n);
  S_inv[0] = D[0].inverse();
  y[0] = -b[0];
  for (size_t k = 1; k < n; ++k) {
    const Matrix3d L = B[k].transpose() * S_inv[k - 1];
    S_inv[k] = (D[k] - L * B[k]).inverse();
    y[k] = -b[k] - L * y[k - 1];
  }
  x[n - 1] = S_inv[n - 1] * y[n - 1];
  for (size_t k = n - 1; k-- > 0;) x[k] = S_inv[k] * (y[k] - B[k + 1] * x[k + 1]);
  return x;
}

// One Gauss-Newton step of the chain, rotations perturbed on the right.
void step(std::vector<Matrix3d>& R, const std::vector<Matrix3d>& given, const std::vector<std::optional<GyroRotation>>& gyro,
          double prior_information) {
  const size_t n = R.size();
  std::vector<Matrix3d> D(n, Matrix3d::Zero()), B(n, Matrix3d::Zero());
  std::vector<Vector3d> b(n, Vector3d::Zero());
  for (size_t k = 0; k < n; ++k) {
    const Vector3d r = so3_log(given[k].transpose() * R[k]);
    const Matrix3d J = right_jacobian_inverse(r);
    D[k] += prior_information * J.transpose() * J;
    b[k] += prior_information * J.transpose() * r;
  }
  for (size_t k = 1; k < n; ++k) {
    if (!gyro[k] || !(gyro[k]->variance > 0.0)) continue;
    const Matrix3d relative = R[k - 1].transpose() * R[k];
    const Vector3d r = so3_log(gyro[k]->R.transpose() * relative);
    const Matrix3d J_k = right_jacobian_inverse(r), J_prev = -J_k * relative.transpose();
    const double w = 1.0 / gyro[k]->variance;
    D[k - 1] += w * J_prev.transpose() * J_prev;
    D[k] += w * J_k.transpose() * J_k;
    B[k] += w * J_prev.transpose() * J_k;
    b[k - 1] += w * J_prev.transpose() * r;
    b[k] += w * J_k.transpose() * r;
  }
  const std::vector<Vector3d> dx = solve_tridiagonal(D, B, b);
  for (size_t k = 0; k < n; ++k) R[k] = R[k] * so3_exp(dx[k]);
}

}  // namespace

RotationSmoothing smooth_rotations(std::vector<Eigen::Isometry3d>& poses, const std::vector<std::optional<GyroRotation>>& gyro) {
  if (poses.size() < 2 || gyro.size() != poses.size()) return {};
  RotationSmoothing s = measure(poses, gyro);
  if (!s.applied) return s;
  const double sigma = 2.0 * s.frame_noise_deg * M_PI / 180.0;
  std::vector<Matrix3d> given(poses.size()), R(poses.size());
  for (size_t k = 0; k < poses.size(); ++k) given[k] = R[k] = poses[k].linear();
  for (int i = 0; i < kIterations; ++i) step(R, given, gyro, 1.0 / (sigma * sigma));
  for (size_t k = 0; k < poses.size(); ++k) {
    poses[k].linear() = R[k];
    poses[k] = normalized(poses[k]);
  }
  return s;
}

}  // namespace gcmap
