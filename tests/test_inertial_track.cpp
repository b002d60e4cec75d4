#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "gcmap/odometry/inertial_track.hpp"
#include "imu_test_util.hpp"

namespace gcmap {
namespace {

Matrix6d well_constrained() {
  Matrix6d info = Matrix6d::Identity();
  info.topLeftCorner<3, 3>() *= 1e6;      // 1 mrad
  info.bottomRightCorner<3, 3>() *= 1e4;  // 1 cm
  return info;
}

// The LiDAR sits 0.1 m ahead of the IMU, turned 90 deg about z; the odometry's frame is the first
// LiDAR pose, tilted against gravity as a sensor on a slope is.
struct Rig {
  test::SmoothTrajectory traj;
  ImuConfig config;
  Eigen::Isometry3d T_world_odom;
  Rig() {
    config.x = 0.1, config.yaw_deg = 90.0;
    T_world_odom = lidar_in_world(0.0);
  }
  // A track given the samples up to `samples_until` (s) and the true sweeps 0.1 s apart from
  // `first` to `last` (both included), registered as `information` says.
  InertialTrack track(double samples_until, int first, int last, const Matrix6d& information) const {
    InertialTrack t(config);
    for (const ImuSample& s : traj.samples(0.0, samples_until, 200.0)) t.add(s);
    for (int k = first; k <= last; ++k) t.observe(0.1 * k, lidar(0.1 * k), &information);
    return t;
  }
  Eigen::Isometry3d lidar_in_world(double t) const { return traj.state(t).T_world_imu * config.T_lidar_imu().inverse(); }
  Eigen::Isometry3d lidar(double t) const { return T_world_odom.inverse() * lidar_in_world(t); }
  double position_error(const Eigen::Isometry3d& T, double t) const { return (T.translation() - lidar(t).translation()).norm(); }
};

TEST(InertialTrack, FindsGravityAndPredictsTheNextSweep) {
  Rig rig;
  InertialTrack track(rig.config);
  for (const ImuSample& s : rig.traj.samples(0.0, 3.0, 200.0)) track.add(s);
  const Matrix6d info = well_constrained();
  for (int k = 0; k <= 10; ++k) {
    EXPECT_FALSE(track.ready()) << k;
    track.observe(0.1 * k, rig.lidar(0.1 * k), &info);
  }
  ASSERT_TRUE(track.ready());
  const Eigen::Vector3d gravity = rig.T_world_odom.linear().transpose() * gravity_vector();
  EXPECT_LT(std::acos(std::clamp(track.gravity().normalized().dot(gravity.normalized()), -1.0, 1.0)), 1e-4);
  const std::optional<Eigen::Isometry3d> next = track.predict(1.1);
  ASSERT_TRUE(next);
  EXPECT_LT(rig.position_error(*next, 1.1), 1e-4);
  EXPECT_LT(rotation_angle(next->inverse() * rig.lidar(1.1)), 1e-4);
  EXPECT_FALSE(track.predict(3.5)) << "beyond the samples";
}

TEST(InertialTrack, CarriesTheOdometryThroughASecondWithoutRegistration) {
  const Rig rig;
  InertialTrack track = rig.track(4.0, 0, 20, well_constrained());
  // Constant velocity would be off by decimetres here (accelerations up to 5 m/s^2).
  for (int k = 21; k <= 30; ++k) {
    const std::optional<Eigen::Isometry3d> T = track.predict(0.1 * k);
    ASSERT_TRUE(T) << k;
    track.observe(0.1 * k, *T, nullptr);
  }
  EXPECT_LT(rig.position_error(*track.predict(3.1), 3.1), 1e-3);
}

TEST(InertialTrack, TheImuHoldsWhatTheRegistrationCannotSee) {
  // Along the LiDAR's x the registration sees nothing (a tunnel) and slides: its x is 2 m/s off.
  const Rig rig;
  InertialTrack track = rig.track(4.0, 0, 15, well_constrained());
  Matrix6d degenerate = well_constrained();
  degenerate(3, 3) = 1e-6;
  for (int k = 16; k <= 30; ++k) {
    const double t = 0.1 * k;
    Eigen::Isometry3d slid = rig.lidar(t);
    slid.translation() += slid.linear().col(0) * 2.0 * (t - 1.5);
    track.observe(t, slid, &degenerate);
  }
  const Eigen::Isometry3d T = track.state().T_world_imu * track.T_imu_lidar();
  EXPECT_LT(rig.position_error(T, 3.0), 1e-3) << "the slide is 3 m";
}

TEST(InertialTrack, ARegistrationTheImuContradictsCountsLittle) {
  // A registration 3 m short along the LiDAR's x and pitched 2 deg (a false minimum, a model that
  // slid), claiming a centimetre and a milliradian: the state stays with the IMU.
  const Rig rig;
  InertialTrack track = rig.track(4.0, 0, 20, well_constrained());
  const Matrix6d info = well_constrained();
  Eigen::Isometry3d wrong = rig.lidar(2.1);
  wrong.translation() -= wrong.linear().col(0) * 3.0;
  wrong.linear() = wrong.linear() * so3_exp(Eigen::Vector3d(0.0, 2.0 * M_PI / 180.0, 0.0));
  track.observe(2.1, wrong, &info);
  const Eigen::Isometry3d T = track.state().T_world_imu * track.T_imu_lidar();
  EXPECT_LT(rig.position_error(T, 2.1), 0.01);
  EXPECT_LT(rotation_angle(T.inverse() * rig.lidar(2.1)) * 180.0 / M_PI, 0.05);
  // The next registration, right again, counts whole.
  track.observe(2.2, rig.lidar(2.2), &info);
  EXPECT_LT(rig.position_error(track.state().T_world_imu * track.T_imu_lidar(), 2.2), 2e-3);
}

TEST(InertialTrack, FollowsTheOdometrysWanderingTilt) {
  // From t = 2 s to 3 s the registered attitude tilts by 2 deg about the odometry's x (as LiDAR
  // odometry's roll wanders), positions staying true: gravity as the registration's frame sees it
  // turns with it, and the state follows (to 0.37 deg five seconds later). Held fixed, it would stay
  // 2 deg off.
  const Rig rig;
  InertialTrack track(rig.config);
  for (const ImuSample& s : rig.traj.samples(0.0, 9.0, 200.0)) track.add(s);
  const Matrix6d info = well_constrained();
  const auto tilt = [](double t) { return so3_exp(Eigen::Vector3d(std::clamp(t - 2.0, 0.0, 1.0) * 2.0 * M_PI / 180.0, 0, 0)); };
  for (int k = 0; k <= 80; ++k) {
    const double t = 0.1 * k;
    Eigen::Isometry3d T = rig.lidar(t);
    T.linear() = tilt(t) * T.linear();
    track.observe(t, T, &info);
  }
  ASSERT_TRUE(track.ready());
  const Eigen::Vector3d seen = tilt(8.0) * rig.T_world_odom.linear().transpose() * gravity_vector();
  const double off = std::acos(std::clamp(track.gravity().normalized().dot(seen.normalized()), -1.0, 1.0));
  EXPECT_LT(off * 180.0 / M_PI, 0.5);
  ASSERT_TRUE(track.last_gravity_turn_deg());
  EXPECT_NEAR(*track.last_gravity_turn_deg(), 2.0, 0.5) << "reported";
}

TEST(InertialTrack, GravityStaysWhereARegistrationLeavesATranslationUnknown) {
  // A tunnel (nothing along the LiDAR's x) whose registered attitude wanders by 1 deg: gravity is
  // held, not moved along with the state it was correlated with while it was free.
  const Rig rig;
  InertialTrack track = rig.track(5.0, 0, 20, well_constrained());
  const Eigen::Vector3d held = track.gravity();
  Matrix6d degenerate = well_constrained();
  degenerate(3, 3) = 1e-6;
  for (int k = 21; k <= 40; ++k) {
    Eigen::Isometry3d T = rig.lidar(0.1 * k);
    T.linear() = T.linear() * so3_exp(Eigen::Vector3d(0.0, (k - 20) * 0.05 * M_PI / 180.0, 0.0));
    track.observe(0.1 * k, T, &degenerate);
  }
  EXPECT_LT((track.gravity() - held).norm(), 1e-12 * held.norm());
}

TEST(InertialTrack, StartsAgainAfterAReset) {
  const Rig rig;
  InertialTrack track = rig.track(3.0, 0, 10, well_constrained());
  ASSERT_TRUE(track.ready());
  track.reset();
  EXPECT_FALSE(track.ready());
  EXPECT_FALSE(track.predict(1.2));
  const Matrix6d info = well_constrained();
  for (int k = 12; k <= 22; ++k) track.observe(0.1 * k, rig.lidar(0.1 * k), &info);
  ASSERT_TRUE(track.ready());
  EXPECT_LT(rig.position_error(*track.predict(2.3), 2.3), 2e-3);
}

TEST(InertialTrack, RegistrationInformationDropsWhatTheScanCannotSee) {
  // Rotation well known; translation strong along two turned axes, a thousandth of that along the
  // third (a tunnel), and a coupling between rotation and translation.
  const Eigen::Matrix3d R = so3_exp(Eigen::Vector3d(0.3, -0.2, 0.5));
  Matrix6d H = Matrix6d::Zero();
  H.topLeftCorner<3, 3>() = 4e6 * Eigen::Matrix3d::Identity();
  H.bottomRightCorner<3, 3>() = R * Eigen::Vector3d(1e6, 2.5e5, 1e3).asDiagonal() * R.transpose();
  H(0, 3) = H(3, 0) = 1e5;
  const Matrix6d I = registration_information(H);
  EXPECT_LT((I - I.transpose()).cwiseAbs().maxCoeff(), 1e-6);
  const auto along = [&](int axis) {
    Vector6d d = Vector6d::Zero();
    d.tail<3>() = R.col(axis);
    return d.dot(I * d);
  };
  EXPECT_NEAR(along(0), 0.25 * 1e6, 1.0);
  EXPECT_NEAR(along(1), 0.25 * 2.5e5 * 0.25, 1.0) << "weighted by the square root of its share (1/4)";
  EXPECT_NEAR(along(2), 0.0, 1e-6) << "degenerate: dropped";
  EXPECT_NEAR(I(0, 0), 0.25 * 4e6, 1e-3);
  EXPECT_EQ(registration_information(Matrix6d::Zero()), Matrix6d::Zero());
}

TEST(InertialTrack, ATranslationTheScanCannotSeeDoesNotPullThePose) {
  // A tunnel's registration along a turned axis, coupled to the rotation: its information has no
  // translation along the axis at all. A pose slid 2 m along it, its rotation 1 mrad off, must cost
  // exactly what the rotation alone costs.
  const Eigen::Vector3d axis = so3_exp(Eigen::Vector3d(0.3, -0.2, 0.5)).col(2);
  // H = G^T G: rows that never move along the axis, and one that does, faintly.
  Eigen::Matrix<double, 7, 6> G;
  for (int i = 0; i < 6; ++i)
    for (int j = 0; j < 6; ++j) G(i, j) = std::sin(1.3 * i + 0.7 * j + 0.1 * i * j) * (j < 3 ? 2000.0 : 1000.0);
  G.topRightCorner<6, 3>() -= G.topRightCorner<6, 3>() * axis * axis.transpose();
  G.row(6) << 0.0, 0.0, 0.0, 10.0 * axis.transpose();
  const Matrix6d H = G.transpose() * G;
  const Eigen::Isometry3d T_imu_lidar = Rig().config.T_lidar_imu().inverse();
  const Eigen::Isometry3d measured = se3_exp((Vector6d() << 0.1, 0.2, -0.3, 40.0, -3.0, 1.0).finished());
  const LidarPoseFactor f(0, measured, registration_information(H), T_imu_lidar);
  const auto error = [&](double slide) {
    Eigen::Isometry3d T_world_lidar = measured * se3_exp((Vector6d() << 1e-3, 0.0, 0.0, 0.0, 0.0, 0.0).finished());
    T_world_lidar.translation() += measured.linear() * (slide * axis);
    NavState s;
    s.T_world_imu = T_world_lidar * T_imu_lidar.inverse();
    const NavState* states[2] = {&s, nullptr};
    return f.error(states);
  };
  ASSERT_GT(error(0.0), 0.1);
  EXPECT_NEAR(error(2.0), error(0.0), 1e-9 * error(0.0));
}

}  // namespace
}  // namespace gcmap
