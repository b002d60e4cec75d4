#pragma once
// The IMU's rotation rates, moved onto the LiDAR's clock and into its frame, for deskewing sweeps
// and predicting their rotation: within a sweep the gyro sees how the turn rate changes, which
// poses registered at 10 Hz cannot. Its bias comes from the rotations the registration measured over
// the last seconds (a low-pass estimate), so a gyro is usable from the first seconds of a drive.
#include <Eigen/Core>
#include <array>
#include <optional>
#include <vector>

#include "gcmap/core/imu_sample.hpp"
#include "gcmap/graph/imu_preintegration.hpp"

namespace gcmap {

class GyroTrack {
 public:
  explicit GyroTrack(const ImuConfig& config);

  // A sample on the IMU's clock and in its frame; stamps increasing. Throws Error otherwise.
  void add(const ImuSample& sample);
  size_t size() const { return samples_.size(); }
  // Whether the samples span [t0, t1] (LiDAR clock).
  bool covers(double t0, double t1) const;
  // R_t0_t for t = t0 + k step, k = 0 .. n-1: the LiDAR frame's rotation since t0, bias removed.
  // Beyond the samples the rate is held.
  std::vector<Eigen::Matrix3d> rotations(double t0, double step, size_t n) const;
  Eigen::Matrix3d rotation(double t0, double t1) const { return rotations(t0, t1 - t0, 2).back(); }
  // R_t0_t1 with another estimate of the bias (rad/s, LiDAR frame).
  Eigen::Matrix3d rotation(double t0, double t1, const Eigen::Vector3d& bias) const {
    return rotations(t0, t1 - t0, 2, bias).back();
  }

  // The registration put the LiDAR at rotations R_world_0 at t0 and R_world_1 at t1: the gyro's
  // rotation between them, off by its bias, moves the bias estimate a step towards agreement.
  void observe(double t0, const Eigen::Matrix3d& R_world_0, double t1, const Eigen::Matrix3d& R_world_1);
  const Eigen::Vector3d& bias() const { return bias_; }  // rad/s, LiDAR frame

  // The clock check: `registered` (rad/s, LiDAR frame) is the registered mean rate over [t0, t1];
  // it is compared with the gyro's mean rate over that window shifted by each candidate offset
  // (up to 0.1 s either way, 1 ms apart).
  void compare_rate(double t0, double t1, const Eigen::Vector3d& registered);
  struct ClockCheck {
    double best_shift = 0.0;                      // s to add to imu.time_offset for the best agreement
    double rms_at_zero = 0.0, rms_at_best = 0.0;  // rad/s
    double rms_rate = 0.0;                        // rad/s: of the registered rates themselves
    // rad/s/sqrt(Hz): the white noise density that explains rms_at_zero: a window of T seconds
    // averages it to density / sqrt(T) per axis. The registration's own error counts in it, so it
    // is an upper bound on the gyro's.
    double noise_density = 0.0;
    size_t windows = 0;
  };
  // Empty before any window was compared.
  std::optional<ClockCheck> clock_check() const;
  // The clock check's noise_density once it has kNoiseWindows windows (5 s of sweeps).
  std::optional<double> measured_noise() const;
  static constexpr size_t kNoiseWindows = 50;
  // The gyro does not follow the registered rotation at any shift (the rotation of T_lidar_imu
  // wrong, another sensor's IMU): after 15 windows, its rates miss the registered ones by more
  // than half their size and by more than 0.02 rad/s, and its axes turned by more than 20 deg
  // would fit them with half that rms.
  bool disagrees() const;
  // The rotation that best turns the gyro's mean rates (at no shift) onto the registered ones.
  Eigen::Matrix3d best_rotation() const;
  // Samples older than t are no longer needed.
  void forget_before(double t);

 private:
  std::vector<Eigen::Matrix3d> rotations(double t0, double step, size_t n, const Eigen::Vector3d& bias) const;
  // ClockCheck::noise_density, without the search over shifts (asked at every deskewing pass).
  double noise_density() const;
  // The rate less `bias` at time t in [samples_[k].stamp, samples_[k+1].stamp] (held beyond).
  Eigen::Vector3d rate(size_t k, double t, const Eigen::Vector3d& bias) const;
  size_t index_before(double t) const;

  // Candidate shifts of the IMU's clock, kShiftStep apart, +-kShiftSteps of them.
  static constexpr int kShiftSteps = 100;
  static constexpr double kShiftStep = 1e-3;
  std::array<double, 2 * kShiftSteps + 1> shift_sse_{};
  double rate_sse_ = 0.0;
  double inverse_span_sum_ = 0.0;                              // 1/s, over the windows
  Eigen::Matrix3d registered_gyro_ = Eigen::Matrix3d::Zero();  // sum of registered * gyro^T at no shift
  size_t shift_windows_ = 0;

  Eigen::Matrix3d R_lidar_imu_;
  double time_offset_;
  std::vector<ImuSample> samples_;  // LiDAR clock and frame, raw rates
  Eigen::Vector3d bias_ = Eigen::Vector3d::Zero();
};

}  // namespace gcmap
