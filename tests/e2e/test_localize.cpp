// Localization on a prior map built by the pipeline from another recording of the same world.
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "gcmap/core/error.hpp"
#include "gcmap/eval/trajectory_metrics.hpp"
#include "gcmap/session/localizer.hpp"
#include "gcmap/sim/simulator.hpp"
#include "test_util.hpp"

namespace gcmap {
namespace {

class PriorMapOfSmallBlock : public ::testing::Test {
 protected:
  // The map: the first 60 frames of the small scenario; the drive to localize: the same world with
  // 3 cm instead of 2 cm range noise (other scans).
  static void SetUpTestSuite() {
    sim::SimulationConfig sc;
    sc.scenario = "small";
    const sim::Simulator mapped(sc);
    MappingPipeline p{MappingConfig{}};
    for (size_t f = 0; f < 60; ++f) p.add_scan(mapped.scan(f), 0.1 * f);
    p.finish();
    auto m = std::make_shared<PriorMap>();
    m->submaps = p.submaps();
    for (const Submap& s : p.submaps()) m->T_map_submap.push_back(p.mapper().output_from_world() * p.mapper().submap_pose(s.id));
    prior = new std::shared_ptr<const PriorMap>(m);
    sc.noise = 0.03;
    drive = new sim::Simulator(sc);
  }
  static void TearDownTestSuite() {
    delete prior;
    delete drive;
  }
  static Eigen::Isometry3d truth(size_t f) { return drive->poses().front().inverse() * drive->poses()[f]; }
  static std::shared_ptr<const PriorMap>* prior;
  static sim::Simulator* drive;
};
std::shared_ptr<const PriorMap>* PriorMapOfSmallBlock::prior = nullptr;
sim::Simulator* PriorMapOfSmallBlock::drive = nullptr;

TEST_F(PriorMapOfSmallBlock, TracksFromAnInitialPoseAndFromGlobalInitialization) {
  for (bool global : {false, true}) {
    Localizer loc(*prior, MappingConfig{});
    if (!global) loc.set_initial_pose(truth(20));
    for (size_t f = 20; f < 40; ++f) {
      const LocalizedFrame lf = loc.add_scan(drive->scan(f), 0.1 * f);
      EXPECT_NE(lf.status, LocalizationStatus::lost) << "frame " << f;
      EXPECT_LT(test::translation_error(lf.T_map_frame, truth(f)), 0.02) << "frame " << f << (global ? " (global)" : "");
      EXPECT_LT(test::rotation_error_deg(lf.T_map_frame, truth(f)), 0.1);
      EXPECT_GT(lf.map_overlap, 0.9);  // the world did not change
    }
    EXPECT_EQ(loc.frames().front().status, global ? LocalizationStatus::relocalized : LocalizationStatus::tracking);
  }
}

TEST_F(PriorMapOfSmallBlock, SweepsDistortedByMotionAreDeskewedBeforeTheMap) {
  // The same route at about 11 m/s, each firing at its own pose: a sweep is smeared by a metre.
  // Taken as instantaneous, the scan registers near its mid-sweep pose, half a sweep from the stamp.
  sim::SimulationConfig sc;
  sc.scenario = "small";
  sc.realism = sim::RealismConfig::none();
  sc.realism->motion_distortion = true;
  const sim::Simulator moving(sc);
  // From the third frame on: the odometry knows no motion for the first frame, and registers the
  // second on the first's smeared sweep.
  double worst[2] = {0.0, 0.0}, squares[2] = {0.0, 0.0};
  for (bool with_times : {false, true}) {
    Localizer loc(*prior, MappingConfig{});
    loc.set_initial_pose(truth(20));
    for (size_t f = 20; f < 40; ++f) {
      PointCloud sweep = moving.scan(f);
      ASSERT_TRUE(sweep.has_times());
      if (!with_times) sweep.times.clear();
      const LocalizedFrame lf = loc.add_scan(std::move(sweep), 0.1 * f);
      ASSERT_NE(lf.status, LocalizationStatus::lost) << "frame " << f;
      EXPECT_EQ(lf.deskewed, with_times && f > 20) << "frame " << f;
      if (f < 22) continue;
      const double e = test::translation_error(lf.T_map_frame, truth(f));
      worst[with_times] = std::max(worst[with_times], e);
      squares[with_times] += e * e;
    }
  }
  const double rms[2] = {std::sqrt(squares[0] / 18), std::sqrt(squares[1] / 18)};
  std::printf("localization of distorted sweeps, rms / largest error: without times %.3f / %.3f m, deskewed %.3f / %.3f m\n",
              rms[0], worst[0], rms[1], worst[1]);
  EXPECT_GT(rms[0], 0.5);
  EXPECT_LT(rms[1], 0.05);
  EXPECT_LT(worst[1], 0.15);  // a corner: the yaw rate changes within the sweep
}

TEST_F(PriorMapOfSmallBlock, OnlyTheSubmapsOverlappingMostAreMatched) {
  int most[2] = {0, 0};
  for (int cap : {8, 2}) {
    MappingConfig config;
    config.localize.max_submaps = cap;
    Localizer loc(*prior, config);
    loc.set_initial_pose(truth(20));
    for (size_t f = 20; f < 30; ++f) {
      const LocalizedFrame lf = loc.add_scan(drive->scan(f), 0.1 * f);
      ASSERT_NE(lf.status, LocalizationStatus::lost) << "frame " << f;
      EXPECT_LT(test::translation_error(lf.T_map_frame, truth(f)), 0.02) << "frame " << f << ", at most " << cap;
      most[cap == 2] = std::max(most[cap == 2], lf.prior_submaps);
    }
  }
  EXPECT_GT(most[0], 2);
  EXPECT_EQ(most[1], 2);
}

TEST_F(PriorMapOfSmallBlock, AChangedWorldIsReportedNeverMistaken) {
  // Seed 2 builds other houses along the same streets: from a known pose tracking goes on and
  // reports the points the map does not explain; without one, nothing is confidently wrong.
  sim::SimulationConfig sc;
  sc.scenario = "small";
  sc.seed = 2;
  const sim::Simulator changed(sc);
  for (bool global : {false, true}) {
    Localizer loc(*prior, MappingConfig{});
    if (!global) loc.set_initial_pose(truth(20));
    int held = 0;
    for (size_t f = 20; f < 35; ++f) {
      const LocalizedFrame lf = loc.add_scan(changed.scan(f), 0.1 * f);
      if (lf.status == LocalizationStatus::lost) continue;
      ++held;
      EXPECT_LT(test::translation_error(lf.T_map_frame, truth(f)), 0.5) << "frame " << f;
      EXPECT_LT(lf.map_overlap, 0.95);
    }
    if (!global) EXPECT_EQ(held, 15);
  }
}

TEST_F(PriorMapOfSmallBlock, MisuseIsAnError) {
  Localizer loc(*prior, MappingConfig{});
  loc.set_initial_pose(truth(20));
  loc.add_scan(drive->scan(20), 2.0);
  EXPECT_THROW(loc.add_scan(drive->scan(21), 1.0), Error);  // stamps going backwards
  MappingConfig other;
  other.global.voxel_resolution = 2.0;
  EXPECT_THROW(Localizer(*prior, other), Error);
  EXPECT_THROW(Localizer(std::make_shared<PriorMap>(), MappingConfig{}), Error);
}

// Two routes through the realistic small block (every realism on: motion distortion, traffic,
// beam calibration errors, dropouts, ...): route 0 mapped by the pipeline, route 1 (the same
// loop from 20 m further on, other noise and traffic) localized on that map from no initial pose,
// with 50 scans dropped on the way (frames 60-109: 5 s, 57 m).
TEST(RealisticRoutes, SecondRouteLocalizesGloballyAndAgainAfterFiftyDroppedScans) {
  sim::SimulationConfig sc;
  sc.scenario = "small";
  sc.realism = sim::RealismConfig::all();
  const sim::Simulator route0(sc);
  MappingPipeline p{MappingConfig{}};
  for (size_t f = 0; f < route0.num_frames(); ++f) p.add_scan(route0.scan(f), 0.1 * f);
  p.finish();
  auto prior = std::make_shared<PriorMap>();
  prior->submaps = p.submaps();
  for (const Submap& s : p.submaps())
    prior->T_map_submap.push_back(p.mapper().output_from_world() * p.mapper().submap_pose(s.id));

  sc.route = 1;
  const sim::Simulator route1(sc);
  Localizer loc(prior, MappingConfig{});
  Poses gt, est;
  int first_fix = -1, lost_after_first_fix = 0, back_after_gap = -1;
  for (size_t f = 0; f < route1.num_frames(); ++f) {
    if (f >= 60 && f < 110) continue;
    const LocalizedFrame lf = loc.add_scan(route1.scan(f), 0.1 * f);
    if (lf.status == LocalizationStatus::lost) {
      lost_after_first_fix += first_fix >= 0;
      continue;
    }
    if (first_fix < 0) first_fix = static_cast<int>(f);
    if (f >= 110 && back_after_gap < 0) back_after_gap = static_cast<int>(f);
    gt.push_back(route0.poses().front().inverse() * route1.poses()[f]);
    est.push_back(lf.T_map_frame);
  }
  // The map's frame is its estimate of route 0's first pose; aligned, what is left is the
  // localization's own error plus the map's (3.6 cm ATE on route 0).
  const AbsoluteError ate = absolute_trajectory_error(gt, est);
  std::printf(
      "realistic route 1 on route 0's map: first fix at frame %d, again at %d after the gap, %d frames lost "
      "after the first fix, ATE %.4f m rmse, %.4f m max\n",
      first_fix, back_after_gap, lost_after_first_fix, ate.rmse, ate.max);
  EXPECT_LE(first_fix, 2);
  EXPECT_LE(back_after_gap, 112);
  EXPECT_LE(lost_after_first_fix, 2);  // right after the gap: no motion known, no dead reckoning
  EXPECT_LT(ate.rmse, 0.05);
  EXPECT_LT(ate.max, 0.2);  // nothing confidently wrong
}

}  // namespace
}  // namespace gcmap
