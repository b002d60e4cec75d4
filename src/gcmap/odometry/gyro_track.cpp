#include "gcmap/odometry/gyro_track.hpp"

#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <string>

#include "gcmap/core/error.hpp"
#include "gcmap/core/se3.hpp"

namespace gcmap {

namespace {

// Each registered rotation moves the bias this fraction of the way to agreeing with it: the
// windows of consecutive frames overlap, and a second of white gyro noise alone is worth about
// its density in rad/s, as much as a MEMS bias; the bias itself wanders over minutes.
constexpr double kBiasGain = 0.02;
// rad/s: a correction beyond this is a registration gone wrong, not a bias (MEMS gyros stay
// within a few hundredths of a rad/s).
constexpr double kMaxBiasStep = 0.05;
// rad: an IMU whose axes fit the registered rates best turned by more than this is misplaced.
constexpr double kMisplacedAngle = 20.0 * M_PI / 180.0;

}  // namespace

GyroTrack::GyroTrack(const ImuConfig& config) : R_lidar_imu_(config.T_lidar_imu().linear()), time_offset_(config.time_offset) {}

void GyroTrack::add(const ImuSample& sample) {
  const double t = sample.stamp - time_offset_;
  if (!samples_.empty() && !(t > samples_.back().stamp))
    throw Error("IMU sample at stamp " + std::to_string(sample.stamp) + " s is not after the one before");
  samples_.push_back({t, R_lidar_imu_ * sample.gyro, R_lidar_imu_ * sample.accel});
}

bool GyroTrack::covers(double t0, double t1) const {
  return samples_.size() >= 2 && samples_.front().stamp <= t0 && samples_.back().stamp >= t1;
}

size_t GyroTrack::index_before(double t) const {
  const auto after =
      std::upper_bound(samples_.begin(), samples_.end(), t, [](double x, const ImuSample& s) { return x < s.stamp; });
  return static_cast<size_t>(std::max<std::ptrdiff_t>(after - samples_.begin() - 1, 0));
}

Eigen::Vector3d GyroTrack::rate(size_t k, double t, const Eigen::Vector3d& bias) const {
  if (k + 1 >= samples_.size()) return samples_.back().gyro - bias;
  const ImuSample &a = samples_[k], &b = samples_[k + 1];
  const double f = std::clamp((t - a.stamp) / (b.stamp - a.stamp), 0.0, 1.0);
  return a.gyro + f * (b.gyro - a.gyro) - bias;
}

std::vector<Eigen::Matrix3d> GyroTrack::rotations(double t0, double step, size_t n) const {
  return rotations(t0, step, n, bias_);
}

std::vector<Eigen::Matrix3d> GyroTrack::rotations(double t0, double step, size_t n, const Eigen::Vector3d& bias) const {
  if (samples_.size() < 2) throw Error("GyroTrack: no IMU samples");
  std::vector<Eigen::Matrix3d> out;
  out.reserve(n);
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  double t = t0;
  size_t k = index_before(t0);
  for (size_t i = 0; i < n; ++i) {
    const double target = t0 + step * static_cast<double>(i);
    // Piecewise between the samples: the mean rate of each piece's ends (second order).
    while (t < target) {
      const double next = k + 1 < samples_.size() ? std::min(target, samples_[k + 1].stamp) : target;
      if (next > t) R *= so3_exp(0.5 * (rate(k, t, bias) + rate(k, next, bias)) * (next - t));
      t = next;
      if (k + 1 < samples_.size() && t >= samples_[k + 1].stamp) ++k;
    }
    out.push_back(R);
  }
  return out;
}

void GyroTrack::observe(double t0, const Eigen::Matrix3d& R_world_0, double t1, const Eigen::Matrix3d& R_world_1) {
  if (!covers(t0, t1) || !(t1 > t0)) return;
  ImuPreintegration pre(ImuBias{bias_, Eigen::Vector3d::Zero()});
  pre.integrate(samples_, t0, t1);
  // delta_R(bias + d) = delta_R exp(dR_dbg d) to first order; d makes it the registered rotation.
  const Eigen::Vector3d r = so3_log(pre.delta_R().transpose() * R_world_0.transpose() * R_world_1);
  const Eigen::Vector3d d = pre.dR_dbg().inverse() * r;
  if (d.allFinite() && d.norm() < kMaxBiasStep) bias_ += kBiasGain * d;
}

void GyroTrack::compare_rate(double t0, double t1, const Eigen::Vector3d& registered) {
  const double reach = kShiftSteps * kShiftStep;
  if (!(t1 > t0) || !covers(t0 - reach, t1 + reach)) return;
  for (int j = 0; j <= 2 * kShiftSteps; ++j) {
    const double shift = (j - kShiftSteps) * kShiftStep;
    // The mean rate over the shifted window by the trapezoid rule on 1 ms steps.
    const int steps = std::max(1, static_cast<int>(std::lround((t1 - t0) / kShiftStep)));
    const double h = (t1 - t0) / steps;
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    size_t k = index_before(t0 + shift);
    for (int i = 0; i <= steps; ++i) {
      const double t = t0 + shift + h * i;
      while (k + 1 < samples_.size() && samples_[k + 1].stamp <= t) ++k;
      sum += (i == 0 || i == steps ? 0.5 : 1.0) * rate(k, t, bias_);
    }
    shift_sse_[static_cast<size_t>(j)] += (sum / steps - registered).squaredNorm();
    if (j == kShiftSteps) registered_gyro_ += registered * (sum / steps).transpose();
  }
  rate_sse_ += registered.squaredNorm();
  inverse_span_sum_ += 1.0 / (t1 - t0);
  ++shift_windows_;
}

std::optional<GyroTrack::ClockCheck> GyroTrack::clock_check() const {
  if (shift_windows_ == 0) return std::nullopt;
  const auto best = std::min_element(shift_sse_.begin(), shift_sse_.end());
  ClockCheck c;
  c.best_shift = (static_cast<int>(best - shift_sse_.begin()) - kShiftSteps) * kShiftStep;
  c.rms_at_best = std::sqrt(*best / shift_windows_);
  c.rms_at_zero = std::sqrt(shift_sse_[kShiftSteps] / shift_windows_);
  c.rms_rate = std::sqrt(rate_sse_ / shift_windows_);
  c.noise_density = noise_density();
  c.windows = shift_windows_;
  return c;
}

double GyroTrack::noise_density() const { return std::sqrt(shift_sse_[kShiftSteps] / (3.0 * inverse_span_sum_)); }

std::optional<double> GyroTrack::measured_noise() const {
  if (shift_windows_ < kNoiseWindows) return std::nullopt;
  return noise_density();
}

Eigen::Matrix3d GyroTrack::best_rotation() const {
  // Wahba's problem: the rotation R maximizing sum registered . (R gyro) = tr(R H^T).
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(registered_gyro_, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d D = Eigen::Matrix3d::Identity();
  D(2, 2) = (svd.matrixU() * svd.matrixV().transpose()).determinant() < 0 ? -1.0 : 1.0;
  return svd.matrixU() * D * svd.matrixV().transpose();
}

bool GyroTrack::disagrees() const {
  const std::optional<ClockCheck> c = clock_check();
  if (!c || c->windows < 15 || !(c->rms_at_best > 0.02 && c->rms_at_best > 0.5 * c->rms_rate)) return false;
  // A registration that errs (a handheld sensor's fast turns) misfits a right gyro as much; a
  // misplaced one is told by a rotation of its axes fitting clearly better. The fit at R:
  // sum |registered - R gyro|^2 = sum |registered - gyro|^2 - 2 tr((R - I) H^T).
  const Eigen::Matrix3d R = best_rotation();
  const double sse_zero = shift_sse_[kShiftSteps];
  const double sse_best = sse_zero - 2.0 * ((R - Eigen::Matrix3d::Identity()) * registered_gyro_.transpose()).trace();
  return so3_log(R).norm() > kMisplacedAngle && sse_best < 0.25 * sse_zero;
}

void GyroTrack::forget_before(double t) {
  const size_t k = index_before(t);
  if (k > 1024) samples_.erase(samples_.begin(), samples_.begin() + static_cast<std::ptrdiff_t>(k));
}

}  // namespace gcmap
