// An IMU end to end through `gcmap map`: found beside a sequence folder or in a bag's sensor_msgs/Imu
// topic, stated in the first lines and stats.json, the same trajectory from every container, and
// nothing changed by --no-imu; bad IMU input is a one-line error naming it.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>

#include "gcmap/eval/trajectory_metrics.hpp"
#include "gcmap/io/bag_writer.hpp"
#include "gcmap/io/imu_io.hpp"
#include "gcmap/io/trajectory_io.hpp"
#include "gcmap/sim/writer.hpp"
#include "test_util.hpp"

namespace gcmap::test {
namespace {

namespace fs = std::filesystem;

// The first 20 frames of the city drive with a 16-beam sensor, motion distortion only, and an IMU.
const std::string kSim = " --scenario city --sensor vlp16 --frames 20 --seed 5 --realism motion_distortion --imu";

class ImuInputs : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new TempDir;
    // Float32 seconds per point: every container holds the simulator's times exactly.
    for (const char* format : {"kitti", "mcap", "db3", "bag"}) {
      const std::string time_field = std::string(format) == "kitti" ? "" : " --time-field velodyne";
      const CliRun r = run_gcmap("simulate -o " + out(format) + kSim + " --format " + format + time_field);
      ASSERT_EQ(r.code, 0) << format << ": " << r.err;
      // An imu.txt beside a bag would be taken before its topic.
      if (std::string(format) != "kitti") fs::remove(out(format) + "/imu.txt");
    }
  }
  static void TearDownTestSuite() { delete dir_; }
  static std::string out(const std::string& name) { return *dir_ / name; }
  static std::string bag(const std::string& format) {
    const BagFormat f = format == "mcap" ? BagFormat::mcap : format == "db3" ? BagFormat::db3 : BagFormat::ros1;
    return sim::simulated_bag_path(out(format), f);
  }
  static CliRun run_map(const std::string& input, const std::string& output, const std::string& extra = "") {
    return run_gcmap("map " + input + " -o " + out(output) + " --quiet --no-render --no-elevation-estimate " + extra);
  }
  static TempDir* dir_;
};

TempDir* ImuInputs::dir_ = nullptr;

TEST_F(ImuInputs, EveryContainerMapsToTheFoldersTrajectory) {
  const CliRun folder = run_map(out("kitti"), "map-kitti");
  ASSERT_EQ(folder.code, 0) << folder.err;
  EXPECT_NE(folder.err.find("IMU: "), std::string::npos) << folder.err;  // what it did, at the end
  const std::string stats = slurp(out("map-kitti") + "/stats.json");
  EXPECT_NE(stats.find("\"imu\":{\"value\":\"gyro deskews each sweep"), std::string::npos) << stats;
  // All but the first sweep (no motion known yet) and the last (the simulated IMU ends at its stamp).
  EXPECT_NE(stats.find("\"gyro_deskewed_sweeps\":18,"), std::string::npos) << stats;
  EXPECT_NE(stats.find("\"imu_file\":\"" + out("kitti") + "/imu.txt\""), std::string::npos);
  const Trajectory reference = read_trajectory(out("map-kitti") + "/trajectory.tum");
  for (const char* format : {"mcap", "db3", "bag"}) {
    SCOPED_TRACE(format);
    const CliRun r = run_map(bag(format), std::string("map-") + format);
    ASSERT_EQ(r.code, 0) << r.err;
    EXPECT_NE(slurp(out(std::string("map-") + format) + "/stats.json").find(": topic /imu\""), std::string::npos);
    const Trajectory t = read_trajectory(out(std::string("map-") + format) + "/trajectory.tum");
    ASSERT_EQ(t.size(), reference.size());
    // The bags' IMU stamps are whole nanoseconds, imu.txt's full doubles.
    for (size_t f = 0; f < t.size(); ++f) EXPECT_LT(translation_error(t.poses[f], reference.poses[f]), 1e-3) << f;
  }
}

TEST_F(ImuInputs, NoImuMapsAsIfThereWereNone) {
  fs::copy(out("kitti"), out("kitti-without"), fs::copy_options::recursive);
  fs::remove(out("kitti-without") + "/imu.txt");
  ASSERT_EQ(run_map(out("kitti-without"), "map-without").code, 0);
  const CliRun r = run_map(out("kitti"), "map-no-imu", "--no-imu");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(slurp(out("map-no-imu") + "/trajectory.tum"), slurp(out("map-without") + "/trajectory.tum"));
  const std::string stats = slurp(out("map-no-imu") + "/stats.json");
  EXPECT_NE(stats.find("imu.use is off (--no-imu)"), std::string::npos);
  EXPECT_EQ(stats.find("\"gyro_deskewed_sweeps\""), std::string::npos);
  EXPECT_EQ(stats.find("\"imu_file\""), std::string::npos);
}

// The drive starts on a slope, so the first frame (LiDAR-only's map frame) leans by 3.4 deg; the
// accelerometer's gravity levels the map. Measured: every pose's vertical within 0.20 deg RMS
// (0.27 at most) of the truth's, against 3.40 deg without the IMU.
TEST_F(ImuInputs, TheAccelerometerLevelsTheMap) {
  const Trajectory truth = read_trajectory(out("kitti") + "/poses_world.txt");
  const auto vertical = [&](const std::string& run, const std::string& extra) {
    const CliRun r = run_map(out("kitti"), run, extra);
    EXPECT_EQ(r.code, 0) << r.err;
    return vertical_error(truth.poses, read_trajectory(out(run) + "/trajectory.kitti").poses);
  };
  const VerticalError with_imu = vertical("level-imu", ""), without = vertical("level-none", "--no-imu");
  EXPECT_LT(with_imu.rmse_deg, 0.5);
  EXPECT_LT(with_imu.max_deg, 0.6);
  EXPECT_GT(without.rmse_deg, 3.0);
  const std::string stats = slurp(out("level-imu") + "/stats.json");
  EXPECT_NE(stats.find("\"map_frame\":\"the first frame's position and heading, z up"), std::string::npos) << stats;
  EXPECT_NE(stats.find("\"gravity\":{\"levelled\":true"), std::string::npos) << stats;
  EXPECT_NE(stats.find("accelerometer levels the map"), std::string::npos) << stats;
  // The occupancy grid needs no levelling by walls.
  const CliRun grid = run_gcmap("export " + out("level-imu") + " --grid --quiet -o " + out("level-grid"));
  ASSERT_EQ(grid.code, 0) << grid.err;
  EXPECT_NE(slurp(out("level-grid") + "/export.json").find("none: the map frame is levelled by the IMU's gravity"),
            std::string::npos);
  // imu.level_map off: the gyro still deskews, the map stays in the first frame.
  const std::string config = out("no-level.yaml");
  std::ofstream(config) << "imu:\n  level_map: false\n";
  const VerticalError off = vertical("level-off", "--config " + config);
  EXPECT_GT(off.rmse_deg, 3.0);
  EXPECT_NE(slurp(out("level-off") + "/stats.json").find("\"gyro_deskewed_sweeps\":18,"), std::string::npos);
}

// The simulated MCAP with its /imu topic written a second time as /imu_raw, as a recording with a
// driver's IMU topic and a filtered one holds.
std::string with_second_imu_topic(const std::string& from, const std::string& to) {
  auto in = open_bag(from);
  auto out = open_bag_writer(to, BagFormat::mcap);
  for (const auto& [name, as] :
       std::vector<std::pair<std::string, std::string>>{{"/points", "/points"}, {"/imu", "/imu"}, {"/imu", "/imu_raw"}}) {
    const uint32_t topic = out->add_topic(as, in->topic(name).type);
    auto cursor = in->read(name);
    BagMessage m;
    while (cursor->next(m)) out->write(topic, m.time_ns, m.data);
  }
  out->close();
  return to;
}

TEST_F(ImuInputs, ABagWithTwoImuTopicsNeedsOneChosen) {
  const std::string two = with_second_imu_topic(bag("mcap"), out("two_imu.mcap"));
  const CliRun r = run_map(two, "two");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("two_imu.mcap: 2 sensor_msgs/Imu topics (/imu, /imu_raw): choose one with --imu-topic"), std::string::npos)
      << r.err;
  const CliRun chosen = run_map(two, "two-chosen", "--imu-topic /imu_raw");
  ASSERT_EQ(chosen.code, 0) << chosen.err;
  ASSERT_EQ(run_map(bag("mcap"), "one").code, 0);
  EXPECT_EQ(slurp(out("two-chosen") + "/trajectory.tum"), slurp(out("one") + "/trajectory.tum"));
}

TEST_F(ImuInputs, BadImuInputIsAOneLineErrorNamingIt) {
  const auto expect_error = [](const CliRun& r, const std::string& what) {
    EXPECT_EQ(r.code, 2);
    EXPECT_NE(r.err.find(what), std::string::npos) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  };
  expect_error(run_map(out("kitti"), "bad1", "--imu " + out("missing.txt")), "missing.txt: --imu: no such file");
  expect_error(run_map(out("kitti"), "bad2", "--imu-topic /imu"), "--imu-topic: the input is not a bag");
  // Stamps on another clock (an IMU counting from its power-up).
  ImuStream s = read_imu_txt(out("kitti") + "/imu.txt");
  for (ImuSample& x : s.samples) x.stamp += 5000.0;
  write_imu_txt(out("shifted.txt"), s.samples);
  expect_error(run_map(out("kitti"), "bad3", "--imu " + out("shifted.txt")), "shifted.txt: the IMU stamps");
}

}  // namespace
}  // namespace gcmap::test
