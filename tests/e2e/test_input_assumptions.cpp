// `gcmap map` on recordings whose stamps and sensor it must find and state: the hku1_livox layout
// (times.txt beside scans/), a simulated drive with a per-point time mistake.
#include <gtest/gtest.h>

#include <filesystem>

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

}  // namespace
}  // namespace gcmap::test
