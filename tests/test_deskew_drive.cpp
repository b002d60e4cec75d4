// Deskewing on the simulator's motion-distorted sweeps (each firing at the pose of its own time):
// a short drive through a corner, tracked with deskewing on, off, and from undistorted sweeps.
#include <tbb/parallel_for.h>

#include <cstdio>

#include "gcmap/eval/trajectory_metrics.hpp"
#include "gcmap/mapping/pipeline.hpp"
#include "gcmap/sim/simulator.hpp"
#include "test_util.hpp"

namespace gcmap {
namespace {

// Odometry frame to frame (rmse).
struct DriveErrors {
  double translation = 0.0;  // m
  double rotation = 0.0;     // deg
};

// Sweeps 80 to 107 of the `loop` drive at 15 m/s (1032 frames): a straight, then the first corner,
// taken in about 1.3 s with yaw rates up to 100 deg/s.
constexpr size_t kFirst = 80, kFrames = 28;

std::vector<PointCloud> simulate(bool distorted, Poses& gt) {
  sim::SimulationConfig sc;
  sc.scenario = "loop";
  sc.frames = 1032;
  sc.realism = sim::RealismConfig::none();
  sc.realism->motion_distortion = distorted;
  const sim::Simulator simulator(sc);
  std::vector<PointCloud> scans(kFrames);
  tbb::parallel_for(size_t{0}, kFrames, [&](size_t k) { scans[k] = simulator.scan(kFirst + k); });
  gt.clear();
  for (size_t k = 0; k < kFrames; ++k) gt.push_back(simulator.poses()[kFirst].inverse() * simulator.poses()[kFirst + k]);
  return scans;
}

DriveErrors track_drive(std::vector<PointCloud> scans, const Poses& gt, bool deskew) {
  MappingConfig config;
  config.loop.enabled = false;
  config.preprocess.deskew = deskew;
  MappingPipeline pipeline(config);
  for (size_t k = 0; k < scans.size(); ++k) pipeline.add_scan(std::move(scans[k]), 0.1 * static_cast<double>(k));
  pipeline.finish();
  // From the 5th frame on: the first sweep is smeared (no motion known yet to deskew it with), and
  // the prediction for the second one is no motion.
  const size_t settled = 4;
  const Poses& est = pipeline.odometry();
  const RelativePoseError e = relative_pose_error(Poses(gt.begin() + settled, gt.end()), Poses(est.begin() + settled, est.end()));
  return {e.translation_rmse, e.rotation_rmse_deg};
}

TEST(DeskewDrive, CompensatesMostOfTheDistortionThroughACorner) {
  Poses gt;
  const std::vector<PointCloud> undistorted_scans = simulate(false, gt), distorted_scans = simulate(true, gt);
  ASSERT_TRUE(distorted_scans[0].has_times());
  const DriveErrors off = track_drive(distorted_scans, gt, false), on = track_drive(distorted_scans, gt, true),
                    undistorted = track_drive(undistorted_scans, gt, true);
  std::printf("odometry RPE m / deg: deskew off %.4f / %.4f, on %.4f / %.4f, undistorted %.4f / %.4f\n",
              off.translation, off.rotation, on.translation, on.rotation, undistorted.translation, undistorted.rotation);
  // Measured: off 0.163 m / 0.658 deg, on 0.033 / 0.125 (a constant velocity over the sweep: 0.039 /
  // 0.140), undistorted 0.0006 / 0.004; deskewing with the motion between the scan stamps (lagging
  // the sweep by a period) gave 0.104 / 0.180. What is left is this corner's curvature, which jumps
  // within a sweep.
  EXPECT_LT(undistorted.translation, 0.01);
  EXPECT_LT(on.translation, 0.4 * off.translation);
  EXPECT_LT(on.rotation, 0.3 * off.rotation);
}

}  // namespace
}  // namespace gcmap
