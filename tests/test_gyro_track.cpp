#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "gcmap/core/error.hpp"
#include "gcmap/core/se3.hpp"
#include "gcmap/odometry/gyro_track.hpp"
#include "test_util.hpp"

namespace gcmap::test {
namespace {

// A LiDAR turning with a rate that changes within a tenth of a second, and its IMU: rotated and
// offset on the LiDAR, its clock 20 ms ahead, its gyro off by a constant bias.
struct Rig {
  ImuConfig config;
  Eigen::Vector3d bias_imu{0.002, -0.003, 0.0015};  // rad/s
  Rig() {
    config.x = 0.05, config.roll_deg = 3.0, config.pitch_deg = -90.0, config.yaw_deg = 30.0;
    config.time_offset = 0.02;
  }
  // The LiDAR's rate in its own frame at LiDAR time t, and its rotation R_world_lidar(t).
  static Eigen::Vector3d rate(double t) { return {0.3 * std::sin(3.0 * t), 0.1, 2.0 * std::sin(20.0 * t)}; }
  // R_world_lidar at t = k step, k = 0 .. n, by fine integration of rate().
  static std::vector<Eigen::Matrix3d> rotations(double step, int n) {
    std::vector<Eigen::Matrix3d> out{Eigen::Matrix3d::Identity()};
    constexpr int kSub = 2000;
    for (int k = 0; k < n; ++k) {
      Eigen::Matrix3d R = out.back();
      for (int i = 0; i < kSub; ++i) R *= so3_exp(rate(step * (k + (i + 0.5) / kSub)) * (step / kSub));
      out.push_back(R);
    }
    return out;
  }
  GyroTrack track(double until) const {
    GyroTrack g(config);
    const Eigen::Matrix3d R_imu_lidar = config.T_lidar_imu().linear().transpose();
    for (double t = 0.0; t <= until; t += 1.0 / 400.0)
      g.add({t + config.time_offset, R_imu_lidar * rate(t) + bias_imu, Eigen::Vector3d(0, 0, 9.8)});
    return g;
  }
};

TEST(GyroTrack, IntegratesTheLidarsRotationOnItsClockAndInItsFrame) {
  Rig rig;
  rig.bias_imu.setZero();
  const GyroTrack g = rig.track(1.0);
  EXPECT_TRUE(g.covers(0.1, 0.9));
  EXPECT_FALSE(g.covers(-0.05, 0.5));  // the first sample is at LiDAR time 0
  // Exact up to the integration of 400 Hz samples; a frame or clock mix-up would be off by 0.01-0.1 rad.
  const std::vector<Eigen::Matrix3d> R_world = Rig::rotations(0.05, 9);
  const Eigen::Matrix3d truth = R_world[7].transpose() * R_world[9];
  const Eigen::Matrix3d R = g.rotation(0.35, 0.45);
  EXPECT_LT(so3_log(truth.transpose() * R).norm(), 1e-4);
  // Table entries agree with single rotations.
  const std::vector<Eigen::Matrix3d> table = g.rotations(0.35, 0.001, 101);
  EXPECT_LT(so3_log(table.back().transpose() * R).norm(), 1e-6);
  EXPECT_LT(so3_log(table[37].transpose() * g.rotation(0.35, 0.387)).norm(), 1e-6);
}

TEST(GyroTrack, LearnsItsBiasFromRegisteredRotations) {
  const Rig rig;
  GyroTrack g = rig.track(40.0);
  const Eigen::Vector3d bias_lidar = rig.config.T_lidar_imu().linear() * rig.bias_imu;
  // Registered rotations with a little noise, every 0.1 s over 40 s.
  std::vector<Eigen::Matrix3d> R = Rig::rotations(0.1, 400);
  for (int k = 0; k <= 400; ++k) R[k] *= so3_exp(Eigen::Vector3d(1e-5 * std::sin(k), 0, 1e-5 * std::cos(3 * k)));
  for (int k = 10; k <= 400; ++k) g.observe(0.1 * (k - 10), R[k - 10], 0.1 * k, R[k]);
  EXPECT_LT((g.bias() - bias_lidar).norm(), 1e-4) << g.bias().transpose() << " vs " << bias_lidar.transpose();
  std::printf("bias err %.3e of %.3e\n", (g.bias() - bias_lidar).norm(), bias_lidar.norm());
  // An observation no bias explains (a failed registration) leaves it alone.
  const Eigen::Vector3d before = g.bias();
  g.observe(39.0, R[390], 40.0, R[400] * so3_exp(Eigen::Vector3d(0.5, 0, 0)));
  EXPECT_EQ(g.bias(), before);
}

TEST(GyroTrack, ItsClockCheckFindsAnOffsetLeftOutOfTheConfig) {
  // The IMU runs 20 ms ahead; the config says 0, then the truth.
  for (const double configured : {0.0, 0.02}) {
    const Rig rig;  // its IMU stamps are 20 ms ahead
    ImuConfig told = rig.config;
    told.time_offset = configured;
    GyroTrack g(told);
    const Eigen::Matrix3d R_imu_lidar = rig.config.T_lidar_imu().linear().transpose();
    for (double t = 0.0; t <= 12.0; t += 1.0 / 400.0)
      g.add({t + rig.config.time_offset, R_imu_lidar * Rig::rate(t), Eigen::Vector3d(0, 0, 9.8)});
    const std::vector<Eigen::Matrix3d> R = Rig::rotations(0.1, 110);
    for (int k = 2; k <= 110; ++k) g.compare_rate(0.1 * (k - 1), 0.1 * k, so3_log(R[k - 1].transpose() * R[k]) / 0.1);
    const auto c = g.clock_check();
    ASSERT_TRUE(c.has_value());
    EXPECT_GE(c->windows, 108u);  // windows whose shifts the samples cover
    EXPECT_NEAR(c->best_shift, 0.02 - configured, 1.5e-3) << configured;
    if (configured == 0.0) EXPECT_GT(c->rms_at_zero, 5.0 * c->rms_at_best);
  }
  EXPECT_FALSE(GyroTrack(ImuConfig{}).clock_check().has_value());
}

TEST(GyroTrack, MeasuresItsWhiteNoiseAgainstTheRegisteredRates) {
  // A turn about one axis, so that registered mean rates are exact: angle(t) = 0.4 (1 - cos 1.5 t) / 1.5.
  // The gyro has white noise of a known density; the mean rate of a 0.1 s window errs by
  // density / sqrt(0.1 s) per axis, whatever the sample rate.
  const auto angle = [](double t) { return 0.4 * (1.0 - std::cos(1.5 * t)) / 1.5; };
  for (const double density : {2.4e-4, 1.7e-3}) {
    const Rig rig;
    GyroTrack g(rig.config);
    const Eigen::Matrix3d R_imu_lidar = rig.config.T_lidar_imu().linear().transpose();
    std::mt19937_64 rng(7);
    std::normal_distribution<double> white(0.0, density * std::sqrt(400.0));
    for (double t = 0.0; t <= 12.0; t += 1.0 / 400.0) {
      const Eigen::Vector3d n(white(rng), white(rng), white(rng));
      g.add({t + rig.config.time_offset, R_imu_lidar * Eigen::Vector3d(0, 0, 0.4 * std::sin(1.5 * t)) + n,
             Eigen::Vector3d(0, 0, 9.8)});
    }
    const auto window = [&](int k) {
      g.compare_rate(0.1 * (k - 1), 0.1 * k, Eigen::Vector3d(0, 0, (angle(0.1 * k) - angle(0.1 * (k - 1))) / 0.1));
    };
    int k = 2;
    for (; k < 2 + static_cast<int>(GyroTrack::kNoiseWindows) - 1; ++k) window(k);
    EXPECT_FALSE(g.measured_noise().has_value());  // too few windows to tell yet
    for (; k <= 115; ++k) window(k);
    ASSERT_TRUE(g.measured_noise().has_value());
    EXPECT_NEAR(*g.measured_noise(), density, 0.15 * density);
  }
}

TEST(GyroTrack, DisagreesWhenTheConfigMisplacesTheImu) {
  // The rig's IMU sits pitched by -90 deg; a config that forgets that mixes its axes up.
  const Rig rig;
  const std::vector<Eigen::Matrix3d> R = Rig::rotations(0.1, 40);
  for (const bool right : {true, false}) {
    ImuConfig told = rig.config;
    if (!right) told.pitch_deg = 0.0;
    GyroTrack g(told);
    const Eigen::Matrix3d R_imu_lidar = rig.config.T_lidar_imu().linear().transpose();
    for (double t = 0.0; t <= 4.0; t += 1.0 / 400.0)
      g.add({t + rig.config.time_offset, R_imu_lidar * Rig::rate(t), Eigen::Vector3d(0, 0, 9.8)});
    for (int k = 2; k <= 14; ++k) g.compare_rate(0.1 * (k - 1), 0.1 * k, so3_log(R[k - 1].transpose() * R[k]) / 0.1);
    EXPECT_FALSE(g.disagrees());  // too few windows to tell yet
    for (int k = 15; k <= 40; ++k) g.compare_rate(0.1 * (k - 1), 0.1 * k, so3_log(R[k - 1].transpose() * R[k]) / 0.1);
    EXPECT_EQ(g.disagrees(), !right);
  }
}

// A handheld sensor's registration errs on fast turns: its rates miss a right gyro's by as much as
// their own size, with no other rotation of the gyro's axes fitting better. The gyro stays.
TEST(GyroTrack, ARegistrationThatErrsDoesNotDropARightGyro) {
  const Rig rig;
  const std::vector<Eigen::Matrix3d> R = Rig::rotations(0.1, 40);
  GyroTrack g(rig.config);
  const Eigen::Matrix3d R_imu_lidar = rig.config.T_lidar_imu().linear().transpose();
  for (double t = 0.0; t <= 4.0; t += 1.0 / 400.0)
    g.add({t + rig.config.time_offset, R_imu_lidar * Rig::rate(t), Eigen::Vector3d(0, 0, 9.8)});
  std::mt19937_64 rng(3);
  std::normal_distribution<double> noise(0.0, 0.8);
  for (int k = 2; k <= 40; ++k) {
    const Eigen::Vector3d rate = so3_log(R[k - 1].transpose() * R[k]) / 0.1;
    g.compare_rate(0.1 * (k - 1), 0.1 * k, rate + Eigen::Vector3d(noise(rng), noise(rng), noise(rng)));
  }
  const auto c = g.clock_check();
  ASSERT_TRUE(c.has_value());
  EXPECT_GT(c->rms_at_best, 0.5 * c->rms_rate);  // what alone dropped it before
  EXPECT_FALSE(g.disagrees());
}

TEST(GyroTrack, RefusesSamplesOutOfOrder) {
  GyroTrack g(ImuConfig{});
  g.add({1.0, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()});
  EXPECT_THROW(g.add({1.0, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()}), Error);
  EXPECT_THROW(g.rotations(0.0, 0.001, 3), Error);  // a single sample spans nothing
}

}  // namespace
}  // namespace gcmap::test
