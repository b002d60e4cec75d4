// gcmap bag-info, map and localize on bags end to end: exit code 2 with one line on bad input.
#include <gtest/gtest.h>

#include <cstdio>
#include <fstream>

#include "bag_test_util.hpp"
#include "gcmap/io/bag_scans.hpp"
#include "gcmap/io/trajectory_io.hpp"
#include "gcmap/sim/simulator.hpp"
#include "test_util.hpp"

namespace gcmap::test {
namespace {

TEST(BagCli, InfoListsTopicsFieldsAndTimes) {
  TempDir dir;
  const std::string path = dir / "drive.mcap";
  CloudLayout layout;
  layout.time = PointTimeConvention::velodyne_time;
  ScanBagWriter w(path, BagFormat::mcap, layout);
  for (int k = 0; k < 3; ++k) w.write(make_scan(50, k), 1673400471.0 + 0.1 * k);
  w.close();
  const CliRun table = run_gcmap("bag-info " + path);
  ASSERT_EQ(table.code, 0) << table.err;
  EXPECT_NE(table.out.find("/points"), std::string::npos) << table.out;
  EXPECT_NE(table.out.find("sensor_msgs/msg/PointCloud2"), std::string::npos);
  EXPECT_NE(table.out.find("x float32, y float32, z float32, intensity float32, time float32"), std::string::npos) << table.out;
  EXPECT_NE(table.out.find("time (s after the header stamp)"), std::string::npos) << table.out;
  EXPECT_NE(table.out.find("2023-01-11 01:27:51"), std::string::npos) << table.out;
  const CliRun json = run_gcmap("bag-info --json " + path);
  ASSERT_EQ(json.code, 0) << json.err;
  EXPECT_NE(json.out.find("\"messages\":3"), std::string::npos) << json.out;
  EXPECT_NE(json.out.find("\"point_time\":\"time (s after the header stamp)\""), std::string::npos) << json.out;

  const CliRun missing = run_gcmap("bag-info " + (dir / "missing.mcap"));
  EXPECT_EQ(missing.code, 2);
  EXPECT_NE(missing.err.find("missing.mcap"), std::string::npos);
  std::string bytes = read_file(path);
  write_file_atomic(dir / "cut.mcap", [&](std::ostream& o) { o << bytes.substr(0, 100); });
  const CliRun cut = run_gcmap("bag-info " + (dir / "cut.mcap"));
  EXPECT_EQ(cut.code, 0) << cut.err;
  EXPECT_NE(cut.out.find("warning:"), std::string::npos) << cut.out;
}

}  // namespace
}  // namespace gcmap::test

namespace gcmap::test {
namespace {

TEST(BagCli, MapReadsAnMcapRecordingEndToEnd) {
  // 15 frames of the simulated block as an MCAP recording (zstd chunks) with Ouster-style point
  // times (all 0: these scans have no motion distortion), mapped straight from the file.
  TempDir dir;
  sim::SimulationConfig sc;
  sc.scenario = "small";
  const sim::Simulator sim(sc);
  {
    CloudLayout layout;
    layout.time = PointTimeConvention::ouster_t;
    BagWriterOptions wo;
    wo.compression = Compression::zstd;
    ScanBagWriter writer(dir / "drive.mcap", BagFormat::mcap, layout, wo, "/os/points");
    for (size_t f = 0; f < 15; ++f) {
      PointCloud scan = sim.scan(f);
      scan.times.assign(scan.size(), 0.0f);
      writer.write(scan, 100.0 + 0.1 * f);
    }
    writer.close();
  }
  const CliRun ok = run_gcmap("map " + (dir / "drive.mcap") + " -o " + (dir / "out") + " --quiet --no-render");
  ASSERT_EQ(ok.code, 0) << ok.err;
  const Trajectory est = read_trajectory(dir / "out/trajectory.tum");
  ASSERT_EQ(est.size(), 15u);
  EXPECT_NEAR(est.stamps[3], 100.3, 1e-6);
  for (size_t f = 0; f < 15; ++f)
    EXPECT_LT(translation_error(est.poses[f], sim.poses().front().inverse() * sim.poses()[f]), 0.05) << f;
  const CliRun wrong_topic = run_gcmap("map " + (dir / "drive.mcap") + " --topic /nope -o " + (dir / "o2"));
  EXPECT_EQ(wrong_topic.code, 2);
  EXPECT_NE(wrong_topic.err.find("/os/points"), std::string::npos) << wrong_topic.err;  // lists the topics there are
  const CliRun folder = run_gcmap("map " + (dir / "out") + " --topic /x -o " + (dir / "o3"));
  EXPECT_EQ(folder.code, 2);
  EXPECT_NE(folder.err.find("apply to bags"), std::string::npos) << folder.err;

  // The same recording localizes on the map it made, from half a second in, where the map put it.
  const CliRun loc = run_gcmap("localize --map " + (dir / "out") + " " + (dir / "drive.mcap") + " --start-time 0.45 -o " +
                               (dir / "loc") + " --global-init --quiet");
  ASSERT_EQ(loc.code, 0) << loc.err;
  const Trajectory localized = read_trajectory(dir / "loc/trajectory.tum");
  ASSERT_EQ(localized.size(), 10u);
  EXPECT_NEAR(localized.stamps[0], 100.5, 1e-6);
  for (size_t k = 1; k < localized.size(); ++k)  // the first frame may wait for its fix
    EXPECT_LT(translation_error(localized.poses[k], est.poses[k + 5]), 0.05) << "frame " << k + 5;
  const CliRun loc_topic = run_gcmap("localize --map " + (dir / "out") + " " + (dir / "drive.mcap") + " --topic /nope -o " +
                                     (dir / "loc2") + " --global-init");
  EXPECT_EQ(loc_topic.code, 2);
  EXPECT_NE(loc_topic.err.find("/os/points"), std::string::npos) << loc_topic.err;
}

}  // namespace
}  // namespace gcmap::test
