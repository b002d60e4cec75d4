// Deskewing on the simulator's motion-distorted sweeps (each firing at the pose of its own time):
// a short drive through a corner, tracked with deskewing on, off, and from undistorted sweeps.
#include <tbb/parallel_for.h>

#include <cstdio>
#include <tuple>

#include "gcmap/calibration/elevation_calibration.hpp"
#include "gcmap/core/se3.hpp"
#include "gcmap/eval/trajectory_metrics.hpp"
#include "gcmap/mapping/pipeline.hpp"
#include "gcmap/sim/imu.hpp"
#include "gcmap/sim/simulator.hpp"
#include "test_util.hpp"

namespace gcmap {
namespace {

// Frame to frame (rmse), m and deg: the odometry, and the mapped trajectory (sweeps deskewed again
// between the poses on both sides, keyframes optimized in their submap).
struct DriveErrors {
  RelativePoseError odometry, trajectory;
};

// Sweeps 80 to 107 of the `loop` drive at 15 m/s (1032 frames): a straight, then the first corner,
// taken in about 1.3 s with yaw rates up to 100 deg/s.
constexpr size_t kFirst = 80, kFrames = 28;

sim::SimulationConfig corner_drive(bool distorted) {
  sim::SimulationConfig sc;
  sc.scenario = "loop";
  sc.frames = 1032;
  sc.realism = sim::RealismConfig::none();
  sc.realism->motion_distortion = distorted;
  return sc;
}

std::vector<PointCloud> simulate(bool distorted, Poses& gt, size_t first = kFirst, size_t frames = kFrames) {
  const sim::Simulator simulator(corner_drive(distorted));
  std::vector<PointCloud> scans(frames);
  tbb::parallel_for(size_t{0}, frames, [&](size_t k) { scans[k] = simulator.scan(first + k); });
  gt.clear();
  for (size_t k = 0; k < frames; ++k) gt.push_back(simulator.poses()[first].inverse() * simulator.poses()[first + k]);
  return scans;
}

// The drive's IMU (default noise unless noise_free), on the clock of the scans given to
// track_drive (frame `first` at 0).
std::vector<ImuSample> simulate_imu(bool noise_free, const Eigen::Matrix3d& R_lidar_imu = Eigen::Matrix3d::Identity(),
                                    const ImuNoise& density = {}, size_t first = kFirst, size_t frames = kFrames) {
  const sim::SimulationConfig sc = corner_drive(true);
  const sim::Simulator simulator(sc);
  sim::ImuSimConfig ic;
  ic.noise = !noise_free;
  ic.density = density;
  ic.T_lidar_imu.linear() = R_lidar_imu;
  std::vector<ImuSample> out;
  for (ImuSample s : sim::simulate_imu(sim::imu_trajectory(simulator, ic.T_lidar_imu), ic, sc.seed).samples) {
    s.stamp -= 0.1 * static_cast<double>(first);
    if (s.stamp > -0.5 && s.stamp < 0.1 * static_cast<double>(frames) + 0.5) out.push_back(s);
  }
  return out;
}

DriveErrors track_drive(std::vector<PointCloud> scans, const Poses& gt, bool deskew, bool redeskew = true,
                        const std::vector<ImuSample>& imu = {}, PipelineStats* stats = nullptr) {
  MappingConfig config;
  config.loop.enabled = false;
  // Ten neighbours per covariance and 1 m odometry voxels, not the defaults twenty and 0.7 m: with
  // either default this one corner's sweeps already register as well as deskewing them again would
  // place them, and the comparisons below need the room (over a whole distorted drive it still
  // helps: docs/benchmarks.md).
  config.preprocess.num_neighbors = 10;
  config.odometry.voxel_resolution = 1.0;
  config.preprocess.deskew = deskew;
  config.preprocess.redeskew = redeskew;
  config.imu.x = sim::ImuSimConfig::default_T_lidar_imu().translation().x();
  config.imu.y = sim::ImuSimConfig::default_T_lidar_imu().translation().y();
  config.imu.z = sim::ImuSimConfig::default_T_lidar_imu().translation().z();
  MappingPipeline pipeline(config);
  for (const ImuSample& s : imu) pipeline.add_imu(s);
  for (size_t k = 0; k < scans.size(); ++k) pipeline.add_scan(std::move(scans[k]), 0.1 * static_cast<double>(k));
  pipeline.finish();
  if (stats) *stats = pipeline.stats();
  // From the 5th frame on: the first sweep is smeared (no motion known yet to deskew it with), and
  // the prediction for the second one is no motion.
  const size_t settled = 4;
  const auto rpe = [&](const Poses& est) {
    return relative_pose_error(Poses(gt.begin() + settled, gt.end()), Poses(est.begin() + settled, est.end()));
  };
  return {rpe(pipeline.odometry()), rpe(pipeline.trajectory())};
}

TEST(DeskewDrive, CompensatesMostOfTheDistortionThroughACorner) {
  Poses gt;
  const std::vector<PointCloud> undistorted_scans = simulate(false, gt), distorted_scans = simulate(true, gt);
  ASSERT_TRUE(distorted_scans[0].has_times());
  const DriveErrors off = track_drive(distorted_scans, gt, false), on = track_drive(distorted_scans, gt, true),
                    once = track_drive(distorted_scans, gt, true, false), undistorted = track_drive(undistorted_scans, gt, true);
  for (const auto& [what, off_e, once_e, on_e, ideal_e] :
       {std::tuple{"odometry", off.odometry, once.odometry, on.odometry, undistorted.odometry},
        std::tuple{"trajectory", off.trajectory, once.trajectory, on.trajectory, undistorted.trajectory}})
    std::printf("%s RPE m / deg: deskew off %.4f / %.4f, once %.4f / %.4f, again %.4f / %.4f, undistorted %.4f / %.4f\n", what,
                off_e.translation_rmse, off_e.rotation_rmse_deg, once_e.translation_rmse, once_e.rotation_rmse_deg,
                on_e.translation_rmse, on_e.rotation_rmse_deg, ideal_e.translation_rmse, ideal_e.rotation_rmse_deg);
  // What is left is this corner's curvature, which jumps within a sweep. Deskewing again once the
  // next sweep is registered must still lower the trajectory's error: little on this one corner,
  // much over a whole drive of them (docs/pipeline.md).
  EXPECT_LT(undistorted.odometry.translation_rmse, 0.01);
  EXPECT_LT(on.odometry.translation_rmse, 0.4 * off.odometry.translation_rmse);
  EXPECT_LT(on.odometry.rotation_rmse_deg, 0.3 * off.odometry.rotation_rmse_deg);
  EXPECT_LT(on.trajectory.translation_rmse, 0.3 * off.trajectory.translation_rmse);
  EXPECT_LT(on.trajectory.rotation_rmse_deg, 0.3 * off.trajectory.rotation_rmse_deg);
  EXPECT_LT(on.trajectory.translation_rmse, 0.98 * once.trajectory.translation_rmse);
}

TEST(DeskewDrive, AGyroFollowsTheTurnRateWithinASweep) {
  Poses gt;
  const std::vector<PointCloud> scans = simulate(true, gt);
  const DriveErrors lidar = track_drive(scans, gt, true), exact = track_drive(scans, gt, true, true, simulate_imu(true)),
                    noisy = track_drive(scans, gt, true, true, simulate_imu(false));
  for (const auto& [what, l, e, n] : {std::tuple{"odometry", lidar.odometry, exact.odometry, noisy.odometry},
                                      std::tuple{"trajectory", lidar.trajectory, exact.trajectory, noisy.trajectory}})
    std::printf("%s RPE m / deg: LiDAR only %.4f / %.4f, exact gyro %.4f / %.4f, gyro of default noise %.4f / %.4f\n", what,
                l.translation_rmse, l.rotation_rmse_deg, e.translation_rmse, e.rotation_rmse_deg, n.translation_rmse,
                n.rotation_rmse_deg);
  EXPECT_LT(exact.trajectory.translation_rmse, 0.5 * lidar.trajectory.translation_rmse);
  EXPECT_LT(exact.trajectory.rotation_rmse_deg, 0.5 * lidar.trajectory.rotation_rmse_deg);
  EXPECT_LT(noisy.trajectory.translation_rmse, 0.5 * lidar.trajectory.translation_rmse);
}

// A gyro seven times better than imu.gyro_noise assumes (a MEMS datasheet's figure): after 5 s its
// density, measured against the registered rotations, weighs its deviations within the sweeps. At
// the assumed density the measurement comes out near it, and the configured one stays.
TEST(DeskewDrive, AGyroBetterThanTheConfigSaysIsMeasured) {
  constexpr size_t kFirstStraight = 40, kLong = 70;  // a straight, then the first corner
  Poses gt;
  const std::vector<PointCloud> scans = simulate(true, gt, kFirstStraight, kLong);
  const double assumed = ImuConfig{}.noise.gyro_noise;
  for (const double density : {2.4e-4, assumed}) {
    ImuNoise noise;
    noise.gyro_noise = density;
    PipelineStats stats;
    track_drive(scans, gt, true, true, simulate_imu(false, Eigen::Matrix3d::Identity(), noise, kFirstStraight, kLong), &stats);
    ASSERT_TRUE(stats.imu_clock.has_value());
    std::printf("gyro %.2e rad/s/sqrt(Hz): measured %.2e, the deskewing took %.2e\n", density, stats.imu_clock->noise_density,
                stats.deskew_gyro_noise);
    // An upper bound: the registration's own error counts in it, the more so over a short drive.
    EXPECT_GT(stats.imu_clock->noise_density, 0.9 * density);
    EXPECT_LT(stats.imu_clock->noise_density, 2.5 * density);
    EXPECT_DOUBLE_EQ(stats.deskew_gyro_noise, density == assumed ? assumed : stats.imu_clock->noise_density);
  }
}

TEST(DeskewDrive, AnImuTheConfigMisplacesIsNoLongerUsed) {
  // The IMU sits rolled by 90 deg; the config says it is aligned with the LiDAR.
  Poses gt;
  const std::vector<PointCloud> scans = simulate(true, gt);
  PipelineStats stats;
  const DriveErrors lidar = track_drive(scans, gt, true),
                    misplaced = track_drive(scans, gt, true, true, simulate_imu(true, so3_exp(Eigen::Vector3d(M_PI / 2, 0, 0))), &stats);
  std::printf("trajectory RPE m / deg: LiDAR only %.4f / %.4f, IMU misplaced %.4f / %.4f, gyro rejected at frame %d\n",
              lidar.trajectory.translation_rmse, lidar.trajectory.rotation_rmse_deg, misplaced.trajectory.translation_rmse,
              misplaced.trajectory.rotation_rmse_deg, stats.gyro_rejected_at.value_or(-1));
  ASSERT_TRUE(stats.gyro_rejected_at.has_value());
  EXPECT_LT(*stats.gyro_rejected_at, 20);
  EXPECT_LT(stats.gyro_deskewed, 20u);
  EXPECT_FALSE(stats.gravity.levelled);  // its accelerometer is dropped with it
}

// The first 110 sweeps of `highway` (every realism key, 26-28 m/s on a straight road between guard
// rails), corrected by beam offsets that the self-calibration once estimated for it. Deskewed with the
// velocity since the last sweep alone, the yaw error of successive frames alternated in sign and
// grew 1.5x per frame from sweep 90 on, to 9 deg by sweep 103.
TEST(DeskewDrive, DoesNotSwingOutOnAStraightHighway) {
  sim::SimulationConfig sc;
  sc.scenario = "highway";
  sc.frames = 110;
  const sim::Simulator simulator(sc);
  std::vector<PointCloud> scans(sc.frames);
  tbb::parallel_for(0, sc.frames, [&](int k) { scans[k] = simulator.scan(k); });
  MappingConfig config;
  config.loop.enabled = false;
  PipelineOptions options;
  options.elevation_calibration = std::make_shared<const ElevationCalibration>(ElevationCalibration::parse(
      "-6.30 0.19307\n-6.00 0.16063\n-5.70 0.18152\n-5.30 -0.07651\n-5.00 -0.07859\n-4.70 0.18263\n-4.30 -0.08657\n"
      "-4.00 -0.05972\n-3.70 -0.08670\n-3.30 0.18038\n-3.00 -0.07137\n-2.70 -0.10851\n-2.30 -0.09320\n-2.00 -0.24630\n"
      "-1.70 -0.27787\n-1.30 -0.19954\n",
      "highway offsets"));
  MappingPipeline pipeline(config, nullptr, options);
  int failed = 0;
  for (int k = 0; k < sc.frames; ++k) failed += pipeline.add_scan(std::move(scans[k]), 0.1 * k).odometry_failed;
  const Poses& odometry = pipeline.odometry();
  double worst_deg = 0.0;
  for (int k = 1; k < sc.frames; ++k) {
    const Eigen::Isometry3d truth = simulator.poses()[k - 1].inverse() * simulator.poses()[k];
    worst_deg = std::max(worst_deg, rotation_angle(truth.inverse() * odometry[k - 1].inverse() * odometry[k]) * 180.0 / M_PI);
  }
  std::printf("worst frame-to-frame rotation error %.3f deg, %d frames placed by the prediction\n", worst_deg, failed);
  EXPECT_EQ(failed, 0);
  // Measured 0.043 deg (the code before: 53 deg).
  EXPECT_LT(worst_deg, 0.2);
}

}  // namespace
}  // namespace gcmap
