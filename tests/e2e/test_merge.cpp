// Merging sessions of different routes through one simulated world (ground truth: poses_world).
#include <algorithm>
#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <optional>

#include "gcmap/core/error.hpp"
#include "gcmap/eval/map_entropy.hpp"
#include "gcmap/eval/trajectory_metrics.hpp"
#include "gcmap/io/file.hpp"
#include "gcmap/io/point_cloud_io.hpp"
#include "gcmap/io/trajectory_io.hpp"
#include "gcmap/mapping/mapper.hpp"
#include "gcmap/session/merge.hpp"
#include "gcmap/session/session.hpp"
#include "gcmap/sim/simulator.hpp"
#include "test_util.hpp"

namespace gcmap {
namespace {

struct MappedDrive {
  Session session;
  std::vector<Eigen::Isometry3d> poses_world;  // ground truth in the world all routes share
};

// Frames [first, first + frames) of a route of the small block, mapped by the pipeline; realistic:
// every realism on (motion distortion, traffic, beam calibration errors, dropouts, ...).
MappedDrive map_route(int route, uint64_t seed, size_t frames, bool realistic = false, size_t first = 0) {
  sim::SimulationConfig sc;
  sc.scenario = "small";
  sc.route = route;
  sc.seed = seed;
  if (realistic) sc.realism = sim::RealismConfig::all();
  const sim::Simulator sim(sc);
  MappingPipeline p{MappingConfig{}};
  std::vector<double> stamps;
  for (size_t f = first; f < first + frames; ++f) {
    p.add_scan(sim.scan(f), 0.1 * f);
    stamps.push_back(0.1 * f);
  }
  p.finish();
  std::vector<Eigen::Isometry3d> poses = sim.poses();
  poses.erase(poses.begin(), poses.begin() + static_cast<std::ptrdiff_t>(first));
  return {make_session(p, stamps), poses};
}

MergeInput input(const MappedDrive& d, const std::string& name) {
  return {name, d.session.submaps, d.session.T_world_submap, d.session.factors, d.session.trajectory};
}

class MergeOfSmallRoutes : public ::testing::Test {
 protected:
  // Routes 0, 1 (the same loop from 20 m further on) and 2 (the next block, from 30 m into route 0,
  // one street shared in the opposite direction) of one world, and route 0 of another world
  // (seed 2: other houses on the same streets); each mapped when a test first needs it.
  static const MappedDrive& drive(int k) {
    static std::vector<std::optional<MappedDrive>> drives(4);
    static constexpr std::array<std::pair<int, uint64_t>, 4> kRoutes{{{0, 1}, {1, 1}, {2, 1}, {0, 2}}};
    if (!drives[k]) drives[k] = map_route(kRoutes[k].first, kRoutes[k].second, k == 3 ? 15 : 35);
    return *drives[k];
  }
  // Frame f of drive k in the frame of drive 0's first pose.
  static Eigen::Isometry3d truth(int k, size_t f) { return drive(0).poses_world[0].inverse() * drive(k).poses_world[f]; }
  // Largest error of drive k's merged trajectory against ground truth beyond the error its own
  // session had (relative to its first frame): what merging added.
  static std::pair<double, double> trajectory_error(const MergeResult& r, int session, int k) {
    double t = 0, a = 0;
    const std::vector<Eigen::Isometry3d>& own = drive(k).session.trajectory;
    for (size_t f = 0; f < r.trajectories[session].size(); ++f) {
      const Eigen::Isometry3d own_truth = drive(k).poses_world[0].inverse() * drive(k).poses_world[f];
      t = std::max(t,
                   test::translation_error(r.trajectories[session][f], truth(k, f)) - test::translation_error(own[f], own_truth));
      a = std::max(
          a, test::rotation_error_deg(r.trajectories[session][f], truth(k, f)) - test::rotation_error_deg(own[f], own_truth));
    }
    return {t, a};
  }
};

TEST_F(MergeOfSmallRoutes, TwoRoutesAreJoinedAtTheirTrueRelativePose) {
  const MergeResult r = merge_sessions({input(drive(0), "A"), input(drive(1), "B")}, MappingConfig{});
  ASSERT_TRUE(r.connected[0] && r.connected[1]);
  EXPECT_EQ(r.placements[1].anchor, 0);
  EXPECT_GT(r.cross_factors, 0u);
  EXPECT_LT(test::translation_error(r.trajectories[0][0], Eigen::Isometry3d::Identity()), 1e-9);
  // The placement of B's first frame, and every frame of both drives after the joint optimization.
  const double t = test::translation_error(r.trajectories[1][0], truth(1, 0));
  const double a = test::rotation_error_deg(r.trajectories[1][0], truth(1, 0));
  std::printf("[ merge    ] B's first pose vs ground truth: %.4f m, %.4f deg; %zu cross-session factors\n", t, a,
              r.cross_factors);
  EXPECT_LT(t, 0.05);
  EXPECT_LT(a, 0.05);
  for (int k : {0, 1}) {
    const auto [tk, ak] = trajectory_error(r, k, k);
    std::printf("[ merge    ] drive %d, worst frame: %.4f m, %.4f deg more than in its own session\n", k, tk, ak);
    EXPECT_LT(tk, 0.02);
    EXPECT_LT(ak, 0.02);
  }
  ASSERT_EQ(r.T_merged_submap.size(), drive(0).session.submaps.size() + drive(1).session.submaps.size());
  EXPECT_EQ(r.first_submap[1], static_cast<int>(drive(0).session.submaps.size()));
}

// Mean map entropy of two sessions' submap clouds, B's submaps placed by T_A_B.
double entropy_of_both(const Session& a, const Session& b, const std::vector<Eigen::Isometry3d>& T_a_submap,
                       const std::vector<Eigen::Isometry3d>& T_a_submap_b) {
  PointCloud map;
  const auto add = [&](const Submap& s, const Eigen::Isometry3d& T) {
    for (const Eigen::Vector3f& p : s.cloud->points) map.points.push_back((T * p.cast<double>()).cast<float>());
  };
  for (size_t j = 0; j < a.submaps.size(); ++j) add(a.submaps[j], T_a_submap[j]);
  for (size_t j = 0; j < b.submaps.size(); ++j) add(b.submaps[j], T_a_submap_b[j]);
  return mean_map_entropy(map).mean;
}

TEST_F(MergeOfSmallRoutes, TheMergedMapIsSharperThanTheBestSingleAlignment) {
  // Before the joint optimization B is placed by its one verified place: the best single
  // alignment of a B submap on an A submap. The joint graph must leave the overlap sharper.
  const Session& a = drive(0).session;
  const Session& b = drive(1).session;
  const MergeResult r = merge_sessions({input(drive(0), "A"), input(drive(1), "B")}, MappingConfig{});
  ASSERT_TRUE(r.connected[1]);
  const SessionPlacement& p = r.placements[1];
  ASSERT_TRUE(p.accepted);
  const Eigen::Isometry3d T_a_b = a.T_world_submap[p.target] * p.T_target_source * b.T_world_submap[p.source].inverse();
  std::vector<Eigen::Isometry3d> placed;
  for (const Eigen::Isometry3d& T : b.T_world_submap) placed.push_back(T_a_b * T);
  const double single = entropy_of_both(a, b, a.T_world_submap, placed);
  const std::vector<Eigen::Isometry3d> merged_a(r.T_merged_submap.begin(), r.T_merged_submap.begin() + r.first_submap[1]);
  const std::vector<Eigen::Isometry3d> merged_b(r.T_merged_submap.begin() + r.first_submap[1], r.T_merged_submap.end());
  const double merged = entropy_of_both(a, b, merged_a, merged_b);
  const double own_a = entropy_of_both(a, Session{}, a.T_world_submap, {});
  std::printf("[ merge    ] mean map entropy: A alone %.4f, A and B by the best single alignment %.4f, merged %.4f\n", own_a,
              single, merged);
  EXPECT_LT(merged, single);
}

TEST_F(MergeOfSmallRoutes, ThreeSessionsInOneCallAndAnotherWorldLeftUnconnected) {
  const MergeResult r =
      merge_sessions({input(drive(0), "A"), input(drive(3), "D"), input(drive(1), "B"), input(drive(2), "C")}, MappingConfig{});
  EXPECT_TRUE(r.connected[0] && r.connected[2] && r.connected[3]);
  EXPECT_FALSE(r.connected[1]);  // seed 2's houses: no verified place with the others
  EXPECT_TRUE(r.trajectories[1].empty());
  EXPECT_EQ(r.first_submap[1], -1);
  EXPECT_EQ(r.T_merged_submap.size(),
            drive(0).session.submaps.size() + drive(1).session.submaps.size() + drive(2).session.submaps.size());
  for (auto [session, k] : {std::pair{2, 1}, {3, 2}}) {
    const auto [t, a] = trajectory_error(r, session, k);
    std::printf("[ merge    ] drive %d of three, worst frame: %.4f m, %.4f deg more than in its own session\n", k, t, a);
    EXPECT_LT(t, 0.02);
    EXPECT_LT(a, 0.02);
  }
}

TEST_F(MergeOfSmallRoutes, MisuseIsAnErrorNamingTheSession) {
  EXPECT_THROW(merge_sessions({input(drive(0), "A")}, MappingConfig{}), Error);
  MergeInput bare = input(drive(1), "bare");
  for (Submap& s : bare.submaps) s.descriptors.clear();
  try {
    merge_sessions({input(drive(0), "A"), bare}, MappingConfig{});
    ADD_FAILURE() << "a session without descriptors cannot be placed";
  } catch (const Error& e) { EXPECT_NE(std::string(e.what()).find("bare: "), std::string::npos) << e.what(); }
  MappingConfig bad;
  bad.merge.max_verifications = 0;
  EXPECT_THROW(merge_sessions({input(drive(0), "A"), input(drive(1), "B")}, bad), Error);
}

TEST(RealisticMerge, RoutesOfOneWorldJoinWhereTheyOverlapAndAnotherWorldStaysApart) {
  // Route 1 starts 20 m into route 0; seed 2 builds other houses along the same streets.
  const MappedDrive a = map_route(0, 1, 80, true), b = map_route(1, 1, 60, true), other = map_route(0, 2, 40, true);
  const MergeResult r = merge_sessions({input(a, "A"), input(other, "other"), input(b, "B")}, MappingConfig{});
  ASSERT_TRUE(r.connected[0] && r.connected[2]);
  EXPECT_FALSE(r.connected[1]);
  // Each session's frame is its own estimate of its first pose (off by tenths of a degree on these
  // scans): B is judged in A's frame as fitted on A's merged trajectory, where the routes overlap.
  Poses truth_a, truth_b;
  for (size_t f = 0; f < 80; ++f) truth_a.push_back(a.poses_world[0].inverse() * a.poses_world[f]);
  const Eigen::Isometry3d T_truth_merged = absolute_trajectory_error(truth_a, r.trajectories[0]).T_gt_est;
  double sum = 0.0, worst = 0.0;
  int overlap = 0;
  for (size_t f = 0; f < 60; ++f) {
    const Eigen::Isometry3d truth = a.poses_world[0].inverse() * b.poses_world[f];
    double nearest = std::numeric_limits<double>::infinity();
    for (const Eigen::Isometry3d& t : truth_a) nearest = std::min(nearest, (t.translation() - truth.translation()).norm());
    if (nearest > 5.0) continue;
    const double e = test::translation_error(T_truth_merged * r.trajectories[2][f], truth);
    sum += e, worst = std::max(worst, e), ++overlap;
  }
  std::printf("[ merge    ] realistic route 1 on route 0 where they overlap (%d frames): mean %.4f m, max %.4f m\n", overlap,
              sum / overlap, worst);
  EXPECT_GT(overlap, 30);
  EXPECT_LT(sum / overlap, 0.05);
  EXPECT_LT(worst, 0.15);

  // Sharper than B placed by its one verified place (see TheMergedMapIsSharperThanTheBestSingleAlignment).
  const SessionPlacement& p = r.placements[2];
  const Eigen::Isometry3d T_a_b =
      a.session.T_world_submap[p.target] * p.T_target_source * b.session.T_world_submap[p.source].inverse();
  std::vector<Eigen::Isometry3d> placed;
  for (const Eigen::Isometry3d& T : b.session.T_world_submap) placed.push_back(T_a_b * T);
  const auto first_b = r.T_merged_submap.begin() + r.first_submap[2];
  const double single = entropy_of_both(a.session, b.session, a.session.T_world_submap, placed);
  const double merged =
      entropy_of_both(a.session, b.session, {r.T_merged_submap.begin(), first_b}, {first_b, r.T_merged_submap.end()});
  std::printf("[ merge    ] realistic, mean map entropy: by the best single alignment %.4f, merged %.4f\n", single, merged);
  EXPECT_LT(merged, single);
}

struct CliResult {
  int code;
  std::string err;
};
CliResult run_cli(const std::string& args, const test::TempDir& dir) {
  const std::string cmd = std::string(GCMAP_CLI) + " " + args + " >/dev/null 2>" + (dir / "err");
  const int status = std::system(cmd.c_str());
  return {WEXITSTATUS(status), read_file(dir / "err")};
}

TEST_F(MergeOfSmallRoutes, CommandWritesTheMergedSessionAndRefusesBadSessionsInOneLine) {
  test::TempDir dir;
  for (int k : {0, 1}) write_session(dir / ("run" + std::to_string(k)) + "/session", drive(k).session);
  const CliResult ok = run_cli("merge " + (dir / "run0") + " " + (dir / "run1") + " -o " + (dir / "merged"), dir);
  ASSERT_EQ(ok.code, 0) << ok.err;
  const Session m = read_session(dir / "merged/session");
  EXPECT_EQ(m.submaps.size(), drive(0).session.submaps.size() + drive(1).session.submaps.size());
  EXPECT_EQ(m.trajectory.size(), 70u);
  EXPECT_TRUE(session_info(m, dir / "merged/session").intensities);
  const Trajectory t1 = read_trajectory(dir / "merged/trajectory_1.kitti");
  ASSERT_EQ(t1.size(), 35u);
  EXPECT_LT(test::translation_error(t1.poses[0], truth(1, 0)), 0.05);
  EXPECT_TRUE(std::filesystem::exists(dir / "merged/map.ply"));
  EXPECT_TRUE(std::filesystem::exists(dir / "merged/merge.json"));

  const CliResult missing = run_cli("merge " + (dir / "run0") + " " + (dir / "nothing") + " -o " + (dir / "m2"), dir);
  EXPECT_EQ(missing.code, 2);
  EXPECT_NE(missing.err.find("nothing"), std::string::npos) << missing.err;
  EXPECT_EQ(std::count(missing.err.begin(), missing.err.end(), '\n'), 1) << missing.err;

  std::filesystem::copy(dir / "run1", dir / "newer", std::filesystem::copy_options::recursive);
  std::string manifest = read_file(dir / "newer/session/manifest.yaml");
  manifest.replace(manifest.find("version: " + std::to_string(kSessionVersion)), 10, "version: 7");
  std::ofstream(dir / "newer/session/manifest.yaml") << manifest;
  const CliResult newer = run_cli("merge " + (dir / "run0") + " " + (dir / "newer") + " -o " + (dir / "m3"), dir);
  EXPECT_EQ(newer.code, 2);
  EXPECT_NE(newer.err.find("version 7"), std::string::npos) << newer.err;
  EXPECT_EQ(std::count(newer.err.begin(), newer.err.end(), '\n'), 1) << newer.err;
  EXPECT_FALSE(std::filesystem::exists(dir / "m3/session"));
}

// render reads map.ply and trajectory.kitti; a merge folder has trajectory_K.kitti per input, so
// the merged map is shown with the first input's trajectory.
CliResult render_intensity(const std::string& merged, const test::TempDir& dir) {
  const std::string view = merged + "_view";
  std::filesystem::create_directories(view);
  std::filesystem::copy_file(merged + "/map.ply", view + "/map.ply");
  std::filesystem::copy_file(merged + "/trajectory_0.kitti", view + "/trajectory.kitti");
  return run_cli("render " + view + " --color intensity --no-graph -o " + view + "/i.png", dir);
}

TEST(MergeCommand, MapHasIntensityWhenEverySessionHasIt) {
  // Two short sessions of one route, the second from 10 frames (about 11 m) further on.
  const MappedDrive a = map_route(0, 1, 20), b = map_route(0, 1, 20, false, 10);
  ASSERT_TRUE(have_intensities(a.session.submaps) && have_intensities(b.session.submaps));  // the simulator's scans have it
  test::TempDir dir;
  write_session(dir / "run0/session", a.session);
  write_session(dir / "run1/session", b.session);
  const CliResult ok = run_cli("merge " + (dir / "run0") + " " + (dir / "run1") + " -o " + (dir / "merged"), dir);
  ASSERT_EQ(ok.code, 0) << ok.err;
  EXPECT_NE(ok.err.find("Merged 2 of 2 sessions"), std::string::npos) << ok.err;
  EXPECT_EQ(ok.err.find("no intensity"), std::string::npos) << ok.err;
  const PointCloud map = read_point_cloud(dir / "merged/map.ply");
  ASSERT_EQ(map.intensities.size(), map.size());
  // The simulator's intensities lie in [0, 1]; voxel means do too, and they vary over the map.
  const auto [lo, hi] = std::minmax_element(map.intensities.begin(), map.intensities.end());
  EXPECT_GE(*lo, 0.f);
  EXPECT_LE(*hi, 1.f);
  EXPECT_GT(*hi - *lo, 0.1f);
  const CliResult render = render_intensity(dir / "merged", dir);
  EXPECT_EQ(render.code, 0) << render.err;
  EXPECT_TRUE(std::filesystem::exists(dir / "merged_view/i.png"));

  // One session from scans without intensity: the map is written without, and the log says whose.
  Session bare = b.session;
  for (Submap& s : bare.submaps) {
    auto cloud = std::make_shared<PointCloud>(*s.cloud);
    cloud->intensities.clear();
    s.cloud = cloud;
  }
  write_session(dir / "bare/session", bare);
  const CliResult without = run_cli("merge " + (dir / "run0") + " " + (dir / "bare") + " -o " + (dir / "m2"), dir);
  ASSERT_EQ(without.code, 0) << without.err;
  EXPECT_NE(without.err.find("map.ply has no intensity: " + (dir / "bare") + " was mapped from scans without intensity.\n"),
            std::string::npos)
      << without.err;
  EXPECT_FALSE(read_point_cloud(dir / "m2/map.ply").has_intensities());
  const CliResult refused = render_intensity(dir / "m2", dir);
  EXPECT_NE(refused.code, 0);
  EXPECT_NE(refused.err.find("no intensity field"), std::string::npos) << refused.err;
}

}  // namespace
}  // namespace gcmap
