// Scan timing: odometry starting at speed and on irregular frame intervals (dropped messages,
// jittered stamps), and per-point times derived from the azimuth of a spinning sensor.
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <random>

#include "gcmap/mapping/pipeline.hpp"
#include "gcmap/sim/simulator.hpp"
#include "test_util.hpp"

namespace gcmap {
namespace {

// The odometry's checks of a doubtful registration must not depend on its voxel size: the tests
// below run on the default 1 m voxels and on 0.7 m, where a registration into another place no
// longer runs away from the prediction.
class OdometryChecks : public ::testing::TestWithParam<double> {
 protected:
  MappingConfig config() const {
    MappingConfig c;
    c.odometry.voxel_resolution = GetParam();
    return c;
  }
};
INSTANTIATE_TEST_SUITE_P(Voxels, OdometryChecks, ::testing::Values(1.0, 0.7));

// The `small` drive (10 Hz, true stamps 0.1 * f, about 1.1 m per frame) with 30 % of its frames
// dropped at random and +-10 ms of stamp jitter: the constant-velocity prediction must follow
// the real intervals, so each relative motion between kept frames stays within 0.2 m of the truth.
TEST_P(OdometryChecks, DroppedFramesAndJitteredStampsKeepFrameToFrameErrorsSmall) {
  sim::SimulationConfig cfg;
  cfg.scenario = "small";
  const sim::Simulator simulator(cfg);
  std::mt19937_64 rng(15);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  std::vector<size_t> kept;
  for (size_t f = 0; f < simulator.num_frames(); ++f) {
    if (f < 3 || uniform(rng) >= 0.3) kept.push_back(f);  // the first frames start the motion model
  }
  std::vector<PointCloud> scans(kept.size());
  tbb::parallel_for(size_t(0), kept.size(), [&](size_t i) { scans[i] = simulator.scan(kept[i]); });

  MappingPipeline pipeline{config()};
  std::vector<Eigen::Isometry3d> odom;
  size_t gaps = 0;
  for (size_t i = 0; i < kept.size(); ++i) {
    const double stamp = 0.1 * kept[i] + (uniform(rng) - 0.5) * 0.02;
    odom.push_back(pipeline.add_scan(std::move(scans[i]), stamp).T_odom);
    if (i > 0 && kept[i] - kept[i - 1] > 1) ++gaps;
  }
  ASSERT_GT(gaps, 20u);  // the test exercises irregular intervals
  const auto& truth = simulator.poses();
  double worst = 0.0;
  for (size_t i = 1; i < kept.size(); ++i) {
    const Eigen::Isometry3d est = odom[i - 1].inverse() * odom[i];
    const Eigen::Isometry3d ref = truth[kept[i - 1]].inverse() * truth[kept[i]];
    const double e = test::translation_error(est, ref);
    worst = std::max(worst, e);
    EXPECT_LT(e, 0.2) << "frames " << kept[i - 1] << " -> " << kept[i];
  }
  EXPECT_EQ(pipeline.stats().odometry_failures, 0u);
  std::printf("worst frame-to-frame error %.3f m over %zu frames (%zu gaps)\n", worst, kept.size(), gaps);
}

// The realistic `highway` starts at 27 m/s (2.7 m per frame) on a road that is degenerate along
// its length, with a per-beam elevation bias that ties the ground rings to the sensor: zero motion
// is a strong false minimum at the start (no velocity known) and whenever a registration slips.
// The odometry must start moving and never jump.
TEST(OdometryTiming, HighwayStartsAtSpeedAndNeverJumps) {
  sim::SimulationConfig cfg;
  cfg.scenario = "highway";
  cfg.frames = 30;
  const sim::Simulator simulator(cfg);
  std::vector<PointCloud> scans(simulator.num_frames());
  tbb::parallel_for(size_t(0), scans.size(), [&](size_t f) { scans[f] = simulator.scan(f); });
  ASSERT_TRUE(scans[1].has_times());  // motion distortion on, so the deskewing path runs too

  MappingPipeline pipeline{MappingConfig{}};
  std::vector<Eigen::Isometry3d> odom;
  for (size_t f = 0; f < scans.size(); ++f) odom.push_back(pipeline.add_scan(std::move(scans[f]), 0.1 * f).T_odom);
  const auto& truth = simulator.poses();
  for (size_t f = 1; f < odom.size(); ++f) {
    const double e = test::translation_error(odom[f - 1].inverse() * odom[f], truth[f - 1].inverse() * truth[f]);
    EXPECT_LT(e, 0.5) << "frames " << f - 1 << " -> " << f;
  }
  EXPECT_EQ(pipeline.stats().odometry_failures, 0u);
}

// A walker starts from a standstill, centimetres per frame, with a sparse non-repetitive sensor
// (Mid-360-like, about 14,000 points a sweep, which samples other surfaces in each sweep). Against a
// model of the first sweep alone, 10-12 of the first 30 frames of each walk failed and the steps
// erred by 0.44 m (median; measured). LiDAR only, the steps must stay within centimetres.
TEST(OdometryTiming, AWalkFromAStandstillRegistersWithinCentimetres) {
  std::vector<double> errors;
  for (const uint64_t seed : {1, 3, 5}) {
    sim::SimulationConfig cfg;
    cfg.scenario = "handheld";
    cfg.frames = 31;
    cfg.seed = seed;
    const sim::Simulator simulator(cfg);
    std::vector<PointCloud> scans(simulator.num_frames());
    tbb::parallel_for(size_t(0), scans.size(), [&](size_t f) { scans[f] = simulator.scan(f); });
    ASSERT_TRUE(scans[1].has_times());
    MappingPipeline pipeline{MappingConfig{}};
    std::vector<Eigen::Isometry3d> odom;
    for (size_t f = 0; f < scans.size(); ++f) odom.push_back(pipeline.add_scan(std::move(scans[f]), 0.1 * f).T_odom);
    const auto& truth = simulator.poses();
    for (size_t f = 1; f < odom.size(); ++f)
      errors.push_back(test::translation_error(odom[f - 1].inverse() * odom[f], truth[f - 1].inverse() * truth[f]));
    EXPECT_EQ(pipeline.stats().odometry_failures, 0u) << "seed " << seed;
  }
  std::sort(errors.begin(), errors.end());
  const double median = errors[errors.size() / 2], p90 = errors[errors.size() * 9 / 10];
  std::printf("the walks' first 30 steps: median error %.3f m, 90th percentile %.3f m, largest %.3f m\n", median, p90,
              errors.back());
  EXPECT_LT(median, 0.08);
  EXPECT_LT(p90, 0.15);
}

// A recording that jumps to another place (two drives in one file, `city` driven twice in a row):
// the last 50 sweeps of the realistic `city`'s first 400 frames, slowing down, then its first 60
// from a standstill, stamps continuing at 10 Hz. The model of the old street cannot place the new
// scans; registering on against it from rest ran away along the street at up to 52 m per frame.
// On finer voxels the registration stays near the prediction instead, with few points matched.
// After a few scans placed by the prediction, the odometry must start a new model and track again.
TEST_P(OdometryChecks, AJumpToAnotherPlaceIsTrackedAgainAfterAFewScans) {
  sim::SimulationConfig cfg;
  cfg.scenario = "city";
  cfg.frames = 400;
  const sim::Simulator simulator(cfg);
  std::vector<size_t> frames;
  for (size_t f = 350; f < 400; ++f) frames.push_back(f);
  const size_t jump = frames.size();
  for (size_t f = 0; f < 60; ++f) frames.push_back(f);
  std::vector<PointCloud> scans(frames.size());
  tbb::parallel_for(size_t(0), frames.size(), [&](size_t i) { scans[i] = simulator.scan(frames[i]); });
  ASSERT_TRUE(scans[1].has_times());  // the deskewing path, as on real recordings

  MappingConfig c = config();
  c.loop.enabled = false;
  MappingPipeline pipeline(c);
  std::vector<Eigen::Isometry3d> odom;
  for (size_t i = 0; i < scans.size(); ++i) odom.push_back(pipeline.add_scan(std::move(scans[i]), 0.1 * i).T_odom);
  EXPECT_GE(pipeline.stats().odometry_failures, 3u);  // the jump was noticed
  const auto& truth = simulator.poses();
  const size_t settled = jump + 8;  // a few scans to notice, one to start the model, one from rest
  for (size_t i = 1; i < frames.size(); ++i) {
    if (i == jump || (i > jump && i < settled)) continue;
    const double e = test::translation_error(odom[i - 1].inverse() * odom[i], truth[frames[i - 1]].inverse() * truth[frames[i]]);
    EXPECT_LT(e, 0.2) << "frames " << frames[i - 1] << " -> " << frames[i];
  }
}

// One ring of a spinning sensor, points in the order the sensor turns: counter-clockwise (azimuth
// increasing) or clockwise from `start_deg`, a full turn less one step.
PointCloud ring(double start_deg, bool clockwise, int steps) {
  PointCloud c;
  for (int k = 0; k < steps; ++k) {
    const double a = (start_deg + (clockwise ? -1.0 : 1.0) * 360.0 * k / steps) * M_PI / 180.0;
    c.points.emplace_back(10.0 * std::cos(a), 10.0 * std::sin(a), 0.5);
  }
  return c;
}

TEST(AzimuthTimes, MonotoneOverTheTurnAndWithinOnePeriod) {
  for (const bool clockwise : {false, true}) {
    for (const double start : {0.0, 180.0, -90.0}) {
      PreprocessConfig config;
      config.sweep_clockwise = clockwise;
      config.sweep_start_deg = start;
      config.sweep_period = 0.1;
      PointCloud c = ring(start + (clockwise ? -0.01 : 0.01), clockwise, 3600);
      times_from_azimuth(c, config);
      ASSERT_EQ(c.times.size(), c.size());
      EXPECT_LT(c.times.front(), 1e-5) << "start " << start << " clockwise " << clockwise;
      EXPECT_GT(c.times.back(), 0.0999);
      for (size_t i = 0; i < c.size(); ++i) {
        EXPECT_GE(c.times[i], 0.f);
        EXPECT_LT(c.times[i], 0.1f);
        if (i > 0) EXPECT_GT(c.times[i], c.times[i - 1]) << "point " << i;
      }
      // Turning the other way, the same points run backwards in time (but the first).
      config.sweep_clockwise = !clockwise;
      times_from_azimuth(c, config);
      for (size_t i = 2; i < c.size(); ++i) EXPECT_LT(c.times[i], c.times[i - 1]) << "point " << i;
    }
  }
  // A point just before the start angle is at the end of the turn, not before its start.
  PreprocessConfig config;
  PointCloud c;
  c.points.emplace_back(10.f, -1e-6f, 0.f);
  times_from_azimuth(c, config);
  EXPECT_GE(c.times[0], 0.f);
  EXPECT_LT(c.times[0], 0.1f);
}

TEST(AzimuthTimes, SetOnlyWhenEnabledAndAbsent) {
  MappingConfig config;
  PointCloud c = ring(0.0, false, 3600);
  EXPECT_FALSE(prepare_scan(c, 0.0, config.preprocess, {}).cloud->has_times());
  config.preprocess.deskew_from_azimuth = true;
  EXPECT_TRUE(prepare_scan(c, 0.0, config.preprocess, {}).cloud->has_times());
}

// The map command's flags reach the configuration it runs with (config.yaml).
TEST(AzimuthTimes, MapFlagsSetTheConfigKeys) {
  test::TempDir tmp;
  const std::string cli = GCMAP_CLI;
  ASSERT_EQ(std::system((cli + " simulate -o " + (tmp / "seq") + " --scenario small --frames 3 >/dev/null 2>&1").c_str()), 0);
  ASSERT_EQ(std::system((cli + " map " + (tmp / "seq") + " -o " + (tmp / "out") +
                         " --no-deskew --deskew-from-azimuth --no-render --quiet >/dev/null 2>&1")
                            .c_str()),
            0);
  const MappingConfig c = MappingConfig::load(tmp / "out/config.yaml");
  EXPECT_FALSE(c.preprocess.deskew);
  EXPECT_TRUE(c.preprocess.deskew_from_azimuth);
}

}  // namespace
}  // namespace gcmap
