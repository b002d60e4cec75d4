// `gcmap simulate --message livox`: the simulated drive as Livox CustomMsg, typed as each driver records
// it (livox_ros_driver/CustomMsg in a ROS 1 bag, livox_ros_driver2/msg/CustomMsg in MCAP and db3), reads back as
// the KITTI layout of the same seed does and maps as the drive written as PointCloud2 with Livox times.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <fstream>

#include "gcmap/core/error.hpp"
#include "gcmap/io/bag_scans.hpp"
#include "gcmap/io/sequence.hpp"
#include "gcmap/sim/writer.hpp"
#include "test_util.hpp"

namespace gcmap::test {
namespace {

// The Livox-Avia-like rosette on the first frames of the city drive, motion distortion only (so that
// points carry times).
const std::string kSim = " --scenario city --sensor avia --frames 10 --seed 7 --realism motion_distortion";
constexpr size_t kFrames = 10;

std::vector<std::pair<double, PointCloud>> read_all(ScanSource& source) {
  std::vector<std::pair<double, PointCloud>> scans;
  while (auto r = source.next()) scans.emplace_back(r->stamp, r->load());
  return scans;
}

class LivoxSim : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new TempDir;
    simulate("kitti", "--format kitti");
    simulate("livox-bag", "--format bag --message livox --compression lz4");
    simulate("livox-mcap", "--format mcap --message livox --compression zstd");
    simulate("livox-db3", "--format db3 --message livox");
    simulate("pc2-bag", "--format bag --time-field livox");
  }
  static void TearDownTestSuite() { delete dir_; }
  static void simulate(const std::string& name, const std::string& args) {
    const CliRun r = run_gcmap("simulate -o " + out(name) + kSim + " " + args);
    ASSERT_EQ(r.code, 0) << name << ": " << r.err;
  }
  static std::string out(const std::string& name) { return *dir_ / name; }
  static std::string bag(const std::string& name) {
    const BagFormat f = name.ends_with("mcap") ? BagFormat::mcap : name.ends_with("db3") ? BagFormat::db3 : BagFormat::ros1;
    return sim::simulated_bag_path(out(name), f);
  }
  static TempDir* dir_;
};

TempDir* LivoxSim::dir_ = nullptr;

TEST_F(LivoxSim, TopicsAreTypedAsTheDriversRecordThem) {
  // ROS 1: the type, the genmsg md5sum and the definition in the connection records (outside the chunks).
  const auto ros1 = open_bag(bag("livox-bag"));
  ASSERT_EQ(ros1->topics().size(), 1u);
  EXPECT_EQ(ros1->topics()[0].type, "livox_ros_driver/CustomMsg");
  const std::string ros1_bytes = slurp(bag("livox-bag"));
  for (const char* s : {"md5sum=e4d6829bdfe657cb6c21a746c86b21a6", "MSG: livox_ros_driver/CustomPoint\nuint32 offset_time",
                        "MSG: std_msgs/Header\nuint32 seq\ntime stamp"})
    EXPECT_NE(ros1_bytes.find(s), std::string::npos) << s;
  // MCAP: the ROS 2 type and a ros2msg schema with the ROS 2 header.
  const auto mcap = open_bag(bag("livox-mcap"));
  ASSERT_EQ(mcap->topics().size(), 1u);
  EXPECT_EQ(mcap->topics()[0].type, "livox_ros_driver2/msg/CustomMsg");
  const std::string mcap_bytes = slurp(bag("livox-mcap"));
  for (const char* s : {"MSG: livox_ros_driver2/CustomPoint\nuint32 offset_time",
                        "MSG: std_msgs/Header\nbuiltin_interfaces/Time stamp", "MSG: builtin_interfaces/Time\nint32 sec"})
    EXPECT_NE(mcap_bytes.find(s), std::string::npos) << s;
  EXPECT_EQ(mcap_bytes.find("uint32 seq"), std::string::npos);
  EXPECT_EQ(open_bag(bag("livox-db3"))->topics().at(0).type, "livox_ros_driver2/msg/CustomMsg");
  EXPECT_NE(slurp(out("livox-bag") + "/scenario.json").find("/points: livox_ros_driver/CustomMsg"), std::string::npos);
}

TEST_F(LivoxSim, ReadsBackAsTheKittiLayout) {
  FolderScanSource kitti_source(out("kitti"));
  const auto kitti = read_all(kitti_source);
  ASSERT_EQ(kitti.size(), kFrames);
  BagScanRecords pc2_source(bag("pc2-bag"), {});
  const auto pc2 = read_all(pc2_source);
  ASSERT_EQ(pc2.size(), kFrames);
  for (const std::string name : {"livox-bag", "livox-mcap", "livox-db3"}) {
    SCOPED_TRACE(name);
    EXPECT_EQ(describe_cloud_topic(*open_bag(bag(name)), "/points").time_field.rfind("offset_time", 0), 0u);
    BagScanRecords source(bag(name), {});
    const auto got = read_all(source);
    ASSERT_EQ(got.size(), kFrames);
    EXPECT_TRUE(source.warnings().empty());
    for (size_t f = 0; f < kFrames; ++f) {
      const PointCloud &a = kitti[f].second, &b = got[f].second;
      ASSERT_EQ(b.points, a.points) << f;
      ASSERT_EQ(b.intensities.size(), a.size()) << f;
      ASSERT_EQ(b.times.size(), a.size()) << f;
      // The bag readers put the stamp at the earliest point, which the rosette does not always fire at
      // the sweep's start: compare absolute times, to the whole ns plus the float step of `times`.
      const double shift = got[f].first - kitti[f].first;
      EXPECT_NEAR(shift, *std::min_element(a.times.begin(), a.times.end()), 1e-9) << f;
      for (size_t i = 0; i < a.size(); ++i) {
        ASSERT_EQ(b.intensities[i], std::round(a.intensities[i] * 255.f)) << f << " point " << i;  // uint8 reflectivity
        const double tolerance = 1e-9 + std::abs(a.times[i]) * std::numeric_limits<float>::epsilon();
        ASSERT_NEAR(shift + b.times[i], a.times[i], tolerance) << f << " point " << i;
      }
      // Bit for bit what PointCloud2's offset_time field gives: the same ns, the same stamp.
      EXPECT_EQ(got[f].first, pc2[f].first) << f;
      ASSERT_EQ(b.times, pc2[f].second.times) << f;
    }
  }
}

TEST_F(LivoxSim, MapsAsPointCloud2WithLivoxTimes) {
  const auto map = [](const std::string& name) {
    const CliRun r = run_gcmap("map " + bag(name) + " -o " + out("map-" + name) + " --quiet --no-render");
    EXPECT_EQ(r.code, 0) << name << ": " << r.err;
    return slurp(out("map-" + name) + "/trajectory.tum");
  };
  const std::string reference = map("pc2-bag");
  EXPECT_EQ(std::count(reference.begin(), reference.end(), '\n'), std::ptrdiff_t(kFrames)) << reference;
  EXPECT_EQ(map("livox-bag"), reference);
  EXPECT_EQ(map("livox-mcap"), reference);
  EXPECT_EQ(map("livox-db3"), reference);
}

TEST(LivoxSimCli, ImpossibleCombinationsAreRefused) {
  TempDir dir;
  const struct {
    const char* args;
    std::vector<std::string> named;  // in the one-line error
  } cases[] = {{"--format kitti --message livox", {"--message", "kitti"}},
               {"--message livox", {"--message", "kitti"}},  // kitti is the default format
               {"--format bag --message livox --time-field ouster", {"--time-field", "--message livox"}},
               {"--format mcap --message custom", {"--message", "pointcloud2 or livox", "'custom'"}}};
  for (const auto& c : cases) {
    const CliRun r = run_gcmap("simulate -o " + (dir / "x") + " --scenario small --frames 2 " + c.args);
    EXPECT_EQ(r.code, 2) << c.args;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << c.args << ": " << r.err;
    for (const std::string& s : c.named) EXPECT_NE(r.err.find(s), std::string::npos) << c.args << ": " << r.err;
    EXPECT_FALSE(std::filesystem::exists(dir / "x")) << c.args;
  }
  // The library refuses it too, naming the folder.
  sim::OutputOptions o;
  o.message = sim::ScanMessage::livox_custom_msg;
  sim::SimulationConfig config;
  config.scenario = "small";
  config.frames = 2;
  EXPECT_THROW(
      {
        try {
          sim::write_simulation(dir / "y", config, o);
        } catch (const Error& e) {
          EXPECT_NE(std::string(e.what()).find("/y: Livox CustomMsg scans need a bag"), std::string::npos) << e.what();
          throw;
        }
      },
      Error);
}

}  // namespace
}  // namespace gcmap::test
