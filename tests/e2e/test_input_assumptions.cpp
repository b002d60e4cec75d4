// `gcmap map` on recordings whose stamps and sensor it must find and state: the hku1_livox layout
// (times.txt beside scans/), a simulated drive with a per-point time mistake.
#include <gtest/gtest.h>

#include <filesystem>

#include "gcmap/calibration/elevation_calibration.hpp"
#include "gcmap/io/trajectory_io.hpp"
#include "test_util.hpp"

namespace gcmap::test {
namespace {

TEST(InputAssumptionsE2E, Hku1StampsBesideTheScansFolder) {
  GCMAP_REQUIRE_SHARED_DATA("hku1_livox");
  TempDir dir;
  const std::string scans = shared_data() + "/hku1_livox/scans";
  const CliRun r = run_gcmap("map " + scans + " -o " + (dir / "out") + " --no-render --max-frames 20");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.err.find("hku1_livox/times.txt, one stamp per scan"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("elevation correction: none (not the KITTI layout"), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find("no stamps"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("beam calibration: not estimated: 0 of the first 3 scans show rings"), std::string::npos) << r.err;
  // The stamps of the run are the file's, not 0.1 s apart.
  const Trajectory t = read_trajectory(dir / "out/trajectory.tum");
  ASSERT_EQ(t.stamps.size(), 20u);
  EXPECT_GT(t.stamps.back() - t.stamps.front(), 3.0);
  const std::string stats = slurp(dir / "out/stats.json");
  EXPECT_NE(stats.find("\"stamp_source\":\"times_file\""), std::string::npos);
}

TEST(InputAssumptionsE2E, MapStatesATimeMistakeOfItsBag) {
  TempDir dir;
  const CliRun sim = run_gcmap("simulate -o " + (dir / "sim") +
                               " --scenario city --sensor vlp16 --frames 20 --seed 5 --realism motion_distortion --format mcap "
                               "--time-field velodyne --time-mistake ms");
  ASSERT_EQ(sim.code, 0) << sim.err;
  const CliRun r = run_gcmap("map " + (dir / "sim/drive.mcap") + " -o " + (dir / "out") + " --no-render --no-deskew");
  EXPECT_NE(r.err.find("[warning] first scan: per-point times span"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("milliseconds where seconds are expected"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("deskewing: off (preprocess.deskew is off"), std::string::npos) << r.err;
  EXPECT_NE(slurp(dir / "out/stats.json").find("milliseconds where seconds"), std::string::npos);
}

// A spinning sensor's beam offsets are estimated before mapping where the drive travels far enough,
// stated, written beside the map and applied; not where it does not, and not with --no-elevation-estimate.
TEST(InputAssumptionsE2E, MapEstimatesBeamElevationsOfASpinningSensorThatTravels) {
  TempDir dir;
  ASSERT_EQ(run_gcmap("simulate -o " + (dir / "sim") + " --scenario city --frames 80 --realism calibration").code, 0);
  const CliRun r = run_gcmap("map " + (dir / "sim") + " -o " + (dir / "out") + " --no-render");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.err.find("beam calibration: estimated before mapping (calibration.estimate_elevation, from the odometry of "
                       "the first 300 frames)"),
            std::string::npos)
      << r.err;
  EXPECT_NE(r.err.find("beam calibration: estimated from the odometry of the first 80 frames"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("elevation_calibration.txt (the beam offsets applied)"), std::string::npos) << r.err;
  EXPECT_GT(ElevationCalibration::load(dir / "out/elevation_calibration.txt").num_offsets(), 10);
  EXPECT_NE(slurp(dir / "out/stats.json").find("\"beam_calibration\":{\"value\":\"estimated\""), std::string::npos);

  const CliRun off = run_gcmap("map " + (dir / "sim") + " -o " + (dir / "off") + " --no-render --no-elevation-estimate");
  ASSERT_EQ(off.code, 0) << off.err;
  EXPECT_NE(off.err.find("beam calibration: none (preprocess.elevation_calibration is empty, calibration.estimate_elevation "
                         "is off)"),
            std::string::npos)
      << off.err;
  EXPECT_FALSE(std::filesystem::exists(dir / "off/elevation_calibration.txt"));

  // localize corrects the scans as the map's were, unless told not to; a map without offsets has none.
  const std::string localize = "localize --max-frames 20 --initial-pose \"0 0 0 0 0 0 1\" " + (dir / "sim");
  const CliRun with = run_gcmap(localize + " --map " + (dir / "out") + " -o " + (dir / "loc"));
  ASSERT_EQ(with.code, 0) << with.err;
  EXPECT_NE(with.err.find("beam calibration: the map's " + (dir / "out/elevation_calibration.txt")), std::string::npos)
      << with.err;
  const CliRun without =
      run_gcmap(localize + " --map " + (dir / "out/session/") + " -o " + (dir / "loc_raw") + " --no-map-calibration");
  ASSERT_EQ(without.code, 0) << without.err;
  EXPECT_NE(slurp(dir / "loc_raw/localization.json").find("\"beam_calibration\":\"none (--no-map-calibration)\""),
            std::string::npos);
  const CliRun plain = run_gcmap(localize + " --map " + (dir / "off") + " -o " + (dir / "loc_off"));
  ASSERT_EQ(plain.code, 0) << plain.err;
  EXPECT_NE(plain.err.find("beam calibration: none (the map was made without beam offsets)"), std::string::npos) << plain.err;

  const CliRun near = run_gcmap("map " + (dir / "sim") + " -o " + (dir / "near") + " --no-render --max-frames 20");
  ASSERT_EQ(near.code, 0) << near.err;
  EXPECT_NE(near.err.find("beam calibration: not estimated: the first 20 frames travel"), std::string::npos) << near.err;
  EXPECT_FALSE(std::filesystem::exists(dir / "near/elevation_calibration.txt"));
}

}  // namespace
}  // namespace gcmap::test
