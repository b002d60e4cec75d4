// The mapping system through its library entry point, MappingPipeline, scan by scan.
#include <tbb/parallel_for.h>

#include <cmath>
#include <limits>
#include <set>

#include "gcmap/core/error.hpp"
#include "gcmap/eval/trajectory_metrics.hpp"
#include "gcmap/mapping/pipeline.hpp"
#include "gcmap/sim/simulator.hpp"
#include "test_util.hpp"

namespace gcmap {
namespace {

class SmallDrive : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    sim::SimulationConfig cfg;
    cfg.scenario = "small";
    simulator = new sim::Simulator(cfg);
    scans = new std::vector<PointCloud>(simulator->num_frames());
  }
  // Simulated on first use: each test (a process of its own under ctest) needs a different prefix.
  static const PointCloud& scan(size_t f) {
    if ((*scans)[f].empty()) {
      tbb::parallel_for(f, std::min(f + 8, scans->size()), [](size_t k) {
        if ((*scans)[k].empty()) (*scans)[k] = simulator->scan(k);
      });
    }
    return (*scans)[f];
  }
  static void TearDownTestSuite() {
    delete scans;
    delete simulator;
  }
  static Eigen::Isometry3d truth(size_t f) { return simulator->poses().front().inverse() * simulator->poses()[f]; }
  static sim::Simulator* simulator;
  static std::vector<PointCloud>* scans;
};
sim::Simulator* SmallDrive::simulator = nullptr;
std::vector<PointCloud>* SmallDrive::scans = nullptr;

TEST_F(SmallDrive, ScanByScanMapsAccuratelyAndClosesTheLoop) {
  MappingPipeline pipeline{MappingConfig{}};
  Poses gt;
  for (size_t f = 0; f < scans->size(); ++f) {
    const Frame frame = pipeline.add_scan(scan(f), 0.1 * f);
    EXPECT_EQ(frame.index, static_cast<int>(f));
    if (f == 0) {
      EXPECT_EQ(frame.status, FrameStatus::keyframe);
      EXPECT_LT(test::translation_error(frame.T_world_frame, Eigen::Isometry3d::Identity()), 1e-9);
    }
    // The streaming estimate is usable while driving: within 0.3 m of the truth at every frame.
    EXPECT_LT(test::translation_error(frame.T_world_frame, truth(f)), 0.3) << "frame " << f;
    gt.push_back(truth(f));
  }
  pipeline.finish();
  const Poses est = pipeline.trajectory();
  ASSERT_EQ(est.size(), gt.size());
  const double ate = absolute_trajectory_error(gt, est).rmse;
  EXPECT_LT(ate, 0.10);
  EXPECT_LT(ate, absolute_trajectory_error(gt, pipeline.odometry()).rmse);

  // Keyframe decisions: exactly the frames reported as keyframes make up the submaps, in order.
  std::vector<int> keyframes, in_submaps;
  for (size_t f = 0; f < pipeline.statuses().size(); ++f)
    if (pipeline.statuses()[f] == FrameStatus::keyframe) keyframes.push_back(static_cast<int>(f));
  for (const Submap& s : pipeline.submaps()) {
    EXPECT_LE(static_cast<int>(s.keyframes.size()), MappingConfig{}.local.max_keyframes);
    in_submaps.insert(in_submaps.end(), s.keyframes.begin(), s.keyframes.end());
  }
  EXPECT_EQ(in_submaps, keyframes);
  const int n = static_cast<int>(pipeline.submaps().size());
  EXPECT_GE(n, 4);

  // The revisit of the start: a matching-cost factor from the last submaps to the first ones, and
  // one accepted explicit loop whose shifted Tukey kernel has let go at the end (satisfied).
  int widest = 0;
  for (const GlobalFactor& f : pipeline.factors())
    if (f.kind == FactorKind::matching_cost) widest = std::max(widest, f.source - f.target);
  EXPECT_GE(widest, n - 2);
  int accepted = 0;
  for (const LoopRecord& l : pipeline.loops()) accepted += l.accepted;
  EXPECT_EQ(accepted, 1);
  const std::vector<FactorEvaluation> eval = pipeline.mapper().evaluate_factors();
  for (size_t f = 0; f < pipeline.factors().size(); ++f) {
    if (pipeline.factors()[f].kind != FactorKind::loop) continue;
    EXPECT_EQ(pipeline.factors()[f].source, n - 1);
    EXPECT_EQ(pipeline.factors()[f].target, 0);
    EXPECT_EQ(eval[f].weight, 0.0);
  }
  const PipelineStats stats = pipeline.stats();
  EXPECT_EQ(stats.frames, scans->size());
  EXPECT_EQ(stats.mapper.global.per_submap.size(), static_cast<size_t>(n));
  EXPECT_GT(pipeline.map(0.1).size(), 10000u);

  // Assembled in slabs of about 2,000 points, the map equals one downsample of every submap point.
  const PointCloud whole = pipeline.mapper().assemble_map(0.1, std::numeric_limits<size_t>::max()),
                   slabs = pipeline.mapper().assemble_map(0.1, 2000);
  ASSERT_EQ(slabs.size(), whole.size());
  size_t submap_points = 0;
  for (const Submap& s : pipeline.submaps()) submap_points += s.cloud->size();
  EXPECT_LT(whole.size(), submap_points);  // voxels shared by several points, across slabs too
  for (size_t i = 0; i < whole.size(); ++i) ASSERT_EQ(slabs.points[i], whole.points[i]) << i;
  EXPECT_THROW(pipeline.mapper().assemble_map(0.0), Error);
}

// run() prepares scans ahead (with their keyframe shapes) and overlaps the odometry of a frame
// with the mapping of the one before; here scans prepared by prepare_scan alone (no shapes) go in
// one after the other. Both give the same frames, poses and counts, bit for bit (every parallel
// sum has a fixed order), an unusable scan included.
TEST_F(SmallDrive, RunGetsWhatScanByScanGets) {
  constexpr size_t kFrames = 60, kEmpty = 30;
  const auto load = [](size_t f) { return f == kEmpty ? PointCloud{} : scan(f); };
  for (size_t f = 0; f < kFrames; ++f) scan(f);  // simulated here, not by run()'s threads
  const MappingConfig config;
  MappingPipeline one_by_one{config};
  std::vector<Frame> expected;
  for (size_t f = 0; f < kFrames; ++f) {
    PreparedScan prepared = prepare_scan(load(f), 0.1 * f, config.preprocess, PipelineOptions{});
    ASSERT_FALSE(prepared.keyframe);
    expected.push_back(one_by_one.add_prepared(std::move(prepared)));
  }
  one_by_one.finish();

  struct Source : ScanSource {
    std::function<PointCloud(size_t)> load;
    size_t next_frame = 0;
    std::optional<ScanRecord> next() override {
      if (next_frame == kFrames) return std::nullopt;
      const size_t f = next_frame++;
      return ScanRecord{0.1 * f, [this, f] { return load(f); }};
    }
  } source;
  source.load = load;
  ASSERT_TRUE(MappingPipeline{config}.prepare(load(0), 0.0).keyframe);
  MappingPipeline pipeline{config};
  std::vector<Frame> frames;
  MappingPipeline::RunOptions options;
  options.on_frame = [&](const Frame& f) { frames.push_back(f); };
  EXPECT_EQ(pipeline.run(source, options), kFrames);
  pipeline.finish();
  ASSERT_EQ(frames.size(), kFrames);
  for (size_t f = 0; f < kFrames; ++f) {
    EXPECT_EQ(frames[f].index, expected[f].index);
    EXPECT_EQ(frames[f].status, expected[f].status) << f;
    EXPECT_EQ(frames[f].T_odom.matrix(), expected[f].T_odom.matrix()) << f;
    EXPECT_EQ(frames[f].T_world_frame.matrix(), expected[f].T_world_frame.matrix()) << f;
  }
  EXPECT_EQ(frames[kEmpty].status, FrameStatus::unusable);
  const Poses a = pipeline.trajectory(), b = one_by_one.trajectory();
  ASSERT_EQ(a.size(), b.size());
  for (size_t f = 0; f < a.size(); ++f) EXPECT_EQ(a[f].matrix(), b[f].matrix()) << f;
  EXPECT_EQ(pipeline.submaps().size(), one_by_one.submaps().size());
  EXPECT_EQ(pipeline.factors().size(), one_by_one.factors().size());
  EXPECT_EQ(pipeline.stats().unusable, 1u);
  EXPECT_EQ(one_by_one.stats().unusable, 1u);
}

TEST_F(SmallDrive, BadScansAreUnusableFramesAndMisuseIsAnError) {
  MappingConfig cfg;
  cfg.loop.enabled = false;
  MappingPipeline pipeline(cfg);
  for (size_t f = 0; f < 5; ++f) EXPECT_NE(pipeline.add_scan(scan(f), 0.1 * f).status, FrameStatus::unusable);
  EXPECT_EQ(pipeline.add_scan(PointCloud{}, 0.5).status, FrameStatus::unusable);
  PointCloud nans;
  nans.points.assign(5000, Eigen::Vector3f::Constant(std::numeric_limits<float>::quiet_NaN()));
  EXPECT_EQ(pipeline.add_scan(nans, 0.6).status, FrameStatus::unusable);
  // A scan whose per-point times do not match its points is used without them.
  PointCloud odd_times = scan(7);
  odd_times.times.assign(7, 0.0f);
  const Frame f7 = pipeline.add_scan(odd_times, 0.7);
  EXPECT_NE(f7.status, FrameStatus::unusable);
  EXPECT_FALSE(f7.deskewed);
  // The unusable frames were placed by the motion model, and frame 7 was registered again.
  EXPECT_LT(test::translation_error(pipeline.trajectory()[5], truth(5)), 0.1);
  EXPECT_LT(test::translation_error(f7.T_world_frame, truth(7)), 0.05);
  EXPECT_THROW(pipeline.add_scan(scan(8), 0.65), Error);  // stamps going backwards
  EXPECT_THROW(pipeline.add_scan(scan(8), std::nan("")), Error);
  EXPECT_EQ(pipeline.num_frames(), 8u);
  pipeline.finish();
  EXPECT_EQ(pipeline.trajectory().size(), 8u);
  EXPECT_EQ(pipeline.stats().unusable, 2u);
  EXPECT_THROW(pipeline.add_scan(scan(8), 0.8), Error);  // after finish()
  MappingConfig bad;
  bad.local.th_min = 2.0;
  try {
    MappingPipeline p(bad);
    ADD_FAILURE() << "an impossible config must be refused";
  } catch (const Error& e) { EXPECT_NE(std::string(e.what()).find("local.th_min"), std::string::npos) << e.what(); }
}

// The sweep of frame f as a sensor moving from pose f to pose f+1 during 0.1 s would record it:
// a point at azimuth a is fired at t = 0.1 (a + pi) / 2 pi from the pose interpolated at t.
PointCloud distorted(const PointCloud& scan, const Eigen::Isometry3d& T_f_next, std::vector<float>* times) {
  PointCloud out = scan;
  const Vector6d xi = se3_log(T_f_next);
  times->resize(scan.size());
  for (size_t i = 0; i < scan.size(); ++i) {
    const Eigen::Vector3f& p = scan.points[i];
    const double t = 0.1 * (std::atan2(p.y(), p.x()) + M_PI) / (2 * M_PI);
    (*times)[i] = static_cast<float>(t);
    out.points[i] = (se3_exp(t / 0.1 * xi).inverse() * p.cast<double>()).cast<float>();
  }
  return out;
}

TEST_F(SmallDrive, PerPointTimesDeskewSweepsDistortedByMotion) {
  // The sensor rests for 3 scans at the first pose, then drives the block at about 10.7 m/s: a
  // sweep is smeared by up to a metre, and by several degrees in the corners.
  const size_t rest = 3, frames = 80;
  MappingConfig cfg;
  cfg.loop.enabled = false;
  const auto run = [&](bool with_times, bool deskew) {
    cfg.preprocess.deskew = deskew;
    MappingPipeline pipeline(cfg);
    Poses gt;
    int deskewed = 0;
    for (size_t k = 0; k < frames; ++k) {
      const size_t f = k < rest ? 0 : k - rest + 1;
      std::vector<float> times;
      PointCloud sweep =
          distorted(scan(f), k + 1 < rest ? Eigen::Isometry3d::Identity() : truth(f).inverse() * truth(f + 1), &times);
      if (with_times) sweep.times = std::move(times);
      deskewed += pipeline.add_scan(std::move(sweep), 0.1 * k).deskewed;
      gt.push_back(truth(f));
    }
    pipeline.finish();
    if (deskew && with_times) EXPECT_EQ(deskewed, static_cast<int>(frames) - 1);  // all but the first
    return absolute_trajectory_error(gt, pipeline.trajectory()).rmse;
  };
  const double without = run(false, true), off = run(true, false), with = run(true, true);
  std::printf("ATE distorted sweeps: without times %.4f m, deskew off %.4f m, deskewed %.4f m\n", without, off, with);
  EXPECT_NEAR(without, off, 1e-9);  // times are ignored when deskew is off
  EXPECT_GT(without, 0.05);
  EXPECT_LT(with, 0.5 * without);
}

TEST_F(SmallDrive, ADriveStartingAtSpeedIsDeskewedFromItsFirstSweep) {
  // No motion is known for the first sweep: it enters the odometry smeared by a metre. Once the
  // second is registered (smeared against smeared), the first is deskewed and replaces itself in
  // the odometry's model and in the open submap; left smeared, the frames after it and with them
  // the map frame (frame 0 the identity) were off by decimetres.
  MappingConfig cfg;
  cfg.loop.enabled = false;
  MappingPipeline pipeline(cfg);
  Poses gt;
  for (size_t f = 0; f < 25; ++f) {  // the straight before the first corner
    std::vector<float> times;
    PointCloud sweep = distorted(scan(f), truth(f).inverse() * truth(f + 1), &times);
    sweep.times = std::move(times);
    pipeline.add_scan(std::move(sweep), 0.1 * f);
    gt.push_back(truth(f));
  }
  pipeline.finish();
  double worst = 0.0;
  for (size_t f = 0; f < gt.size(); ++f) worst = std::max(worst, test::translation_error(pipeline.trajectory()[f], gt[f]));
  std::printf("starting at speed: largest error against the truth (frame 0 the identity) %.4f m\n", worst);
  EXPECT_LT(worst, 0.02);  // 0.61 m with the first sweep left smeared
}

}  // namespace
}  // namespace gcmap
