#include <tbb/global_control.h>

#include "gcmap/core/error.hpp"
#include "gcmap/io/point_cloud_io.hpp"
#include "gcmap/io/trajectory_io.hpp"
#include "gcmap/sim/simulator.hpp"
#include "test_util.hpp"

namespace gcmap {
namespace {

TEST(Simulator, ScansAreDeterministicAndDense) {
  sim::SimulationConfig cfg;
  cfg.scenario = "small";
  const sim::Simulator a(cfg);
  const PointCloud s1 = a.scan(7);
  PointCloud s2;
  {
    tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
    s2 = sim::Simulator(cfg).scan(7);
  }
  ASSERT_EQ(s1.size(), s2.size());
  for (size_t i = 0; i < s1.size(); i += 101) ASSERT_EQ(s1.points[i], s2.points[i]);
  EXPECT_GT(s1.size(), 80000u);   // ~100k returns per HDL-64 scan
  EXPECT_LT(s1.size(), 115200u);  // never more than the rays cast
  // Ranges stay within the sensor's limits.
  for (size_t i = 0; i < s1.size(); i += 53) {
    EXPECT_GE(s1.points[i].norm(), 2.0f - 0.2f);
    EXPECT_LE(s1.points[i].norm(), 120.2f);
  }
}

TEST(Simulator, ScenariosRevisitPlaces) {
  sim::SimulationConfig cfg;
  cfg.scenario = "small";
  const sim::Simulator small(cfg);
  EXPECT_EQ(small.num_frames(), 150u);
  const auto& p = small.poses();
  EXPECT_LT((p.back().translation() - p.front().translation()).norm(), 15.0);  // closes the loop

  cfg.scenario = "loop";
  const sim::Simulator loop(cfg);
  EXPECT_EQ(loop.num_frames(), 1500u);
  EXPECT_NEAR(loop.path_length(), 1550.0, 60.0);
  // A revisit driven in the opposite direction: some late frame is near an early one with the
  // heading reversed.
  bool opposite = false;
  for (size_t i = 0; i < 700; i += 5) {
    for (size_t j = 900; j < loop.num_frames(); j += 5) {
      if ((loop.poses()[i].translation() - loop.poses()[j].translation()).head<2>().norm() > 6.0) continue;
      const double cos_heading = loop.poses()[i].linear().col(0).dot(loop.poses()[j].linear().col(0));
      opposite |= cos_heading < -0.9;
    }
  }
  EXPECT_TRUE(opposite);
  cfg.scenario = "nowhere";
  EXPECT_THROW(sim::Simulator{cfg}, Error);
}

TEST(Simulator, WritesKittiLayout) {
  test::TempDir dir;
  sim::SimulationConfig cfg;
  cfg.scenario = "small";
  cfg.frames = 3;
  cfg.sensor = "vlp16";
  sim::write_simulation(dir.path.string(), cfg);
  const Trajectory gt = read_trajectory(dir / "poses.txt");
  ASSERT_EQ(gt.size(), 3u);
  EXPECT_LT(test::translation_error(gt.poses[0], Eigen::Isometry3d::Identity()), 1e-9);
  const PointCloud scan = read_point_cloud(dir / "velodyne/000002.bin");
  EXPECT_GT(scan.size(), 10000u);
  EXPECT_TRUE(std::filesystem::exists(dir / "times.txt"));
  EXPECT_TRUE(std::filesystem::exists(dir / "scenario.json"));
}

}  // namespace
}  // namespace gcmap
