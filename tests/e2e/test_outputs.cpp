// What gcmap map writes keeps what the input had (intensity), and its progress agrees with its summary.
#include <regex>

#include "gcmap/io/point_cloud_io.hpp"
#include "test_util.hpp"

namespace gcmap {
namespace {

// The last match of `re` in `text` (its first group), or -1.
long last_count(const std::string& text, const std::regex& re) {
  long value = -1;
  for (auto it = std::sregex_iterator(text.begin(), text.end(), re); it != std::sregex_iterator(); ++it)
    value = std::stol((*it)[1]);
  return value;
}

class SmallDriveWithIntensity : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir = new test::TempDir();
    const test::CliRun sim = test::run_gcmap("simulate --scenario small --frames 40 --realism all -o " + (*dir / "sim"));
    ASSERT_EQ(sim.code, 0) << sim.err;
    // Not --quiet: stderr is a file here, so progress comes as log lines.
    map = new test::CliRun(test::run_gcmap("map " + (*dir / "sim") + " -o " + (*dir / "out") + " --device cpu --no-render"));
  }
  static void TearDownTestSuite() {
    delete map;
    delete dir;
  }
  static test::TempDir* dir;
  static test::CliRun* map;
};
test::TempDir* SmallDriveWithIntensity::dir = nullptr;
test::CliRun* SmallDriveWithIntensity::map = nullptr;

TEST_F(SmallDriveWithIntensity, MapKeepsTheScansIntensityAndRendersByIt) {
  ASSERT_EQ(map->code, 0) << map->err;
  const PointCloud ply = read_point_cloud(*dir / "out/map.ply");
  ASSERT_TRUE(ply.has_intensities());
  ASSERT_EQ(ply.intensities.size(), ply.size());
  // The simulator's intensities lie in [0, 1]; means per voxel do too, and they vary over the map.
  float lo = 1.f, hi = 0.f;
  for (float v : ply.intensities) lo = std::min(lo, v), hi = std::max(hi, v);
  EXPECT_GE(lo, 0.f);
  EXPECT_LE(hi, 1.f);
  EXPECT_GT(hi - lo, 0.1f);
  const test::CliRun render = test::run_gcmap("render " + (*dir / "out") + " --color intensity -o " + (*dir / "i.png"));
  EXPECT_EQ(render.code, 0) << render.err;
}

TEST_F(SmallDriveWithIntensity, LastProgressLineCountsAgreeWithTheSummaryAndStats) {
  ASSERT_EQ(map->code, 0) << map->err;
  const std::string& err = map->err;
  const long submaps = last_count(err, std::regex("submaps (\\d+)  factors")),
             factors = last_count(err, std::regex("submaps \\d+  factors (\\d+)"));
  ASSERT_NE(err.find("final optimization, iteration"), std::string::npos) << err;
  // The summary: "Mapped N frames in ...: S submaps, F global factors".
  EXPECT_EQ(submaps, last_count(err, std::regex("(\\d+) submaps, \\d+ global factors"))) << err;
  EXPECT_EQ(factors, last_count(err, std::regex("\\d+ submaps, (\\d+) global factors"))) << err;
  const std::string stats = test::slurp(*dir / "out/stats.json");
  EXPECT_EQ(submaps, last_count(stats, std::regex("\"submaps\":(\\d+)"))) << stats;
  EXPECT_EQ(factors, last_count(stats, std::regex("\"factors\":(\\d+)"))) << stats;
  EXPECT_EQ(last_count(err, std::regex("final optimization, iteration (\\d+)")),
            last_count(stats, std::regex("\"final_iterations\":(\\d+)")));
  EXPECT_NE(err.find("writing outputs, step"), std::string::npos) << err;
}

}  // namespace
}  // namespace gcmap
