// gcmap export --grid and --per-scan on a small simulated drive: the grid against the simulator's
// walls, the per-scan files against the scans moved by the trajectory.
#include <array>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>

#include "gcmap/io/las.hpp"
#include "gcmap/io/point_cloud_io.hpp"
#include "gcmap/io/sequence.hpp"
#include "gcmap/io/trajectory_io.hpp"
#include "grid_truth.hpp"
#include "test_util.hpp"

namespace gcmap {
namespace {

namespace fs = std::filesystem;

constexpr int kFrames = 40;
constexpr const char* kRealism = "motion_distortion,range_noise";  // per-point times, noisy ranges

sim::SimulationConfig drive_config(const std::string& scenario, int frames) {
  sim::SimulationConfig c;
  c.scenario = scenario;
  c.frames = frames;
  c.realism = sim::parse_realism(kRealism);
  return c;
}

// A simulated drive mapped once per test suite.
template <const char* kScenario>
class MappedDrive : public ::testing::Test {
 public:
  static sim::Simulator simulator() { return sim::Simulator(drive_config(kScenario, kFrames)); }

 protected:
  static void SetUpTestSuite() {
    dir = new test::TempDir();
    const auto s = test::run_gcmap(std::string("simulate --scenario ") + kScenario + " --frames " + std::to_string(kFrames) +
                                   " --realism " + kRealism + " -o " + (*dir / "sim"));
    ASSERT_EQ(s.code, 0) << s.err;
    const auto m = test::run_gcmap("map " + (*dir / "sim") + " -o " + (*dir / "out") + " --device cpu --no-render --quiet");
    ASSERT_EQ(m.code, 0) << m.err;
  }
  static void TearDownTestSuite() { delete dir; }
  static test::TempDir* dir;
};
template <const char* kScenario>
test::TempDir* MappedDrive<kScenario>::dir = nullptr;

// The first 40 frames of the city drive: a crossing, from a stop, buildings, poles and parked cars.
constexpr char kCity[] = "city";
using SimulatedDriveExport = MappedDrive<kCity>;

// Moves a folder away for the scope: the recording gone from where stats.json says.
struct MovedAway {
  std::string from, to;
  MovedAway(std::string a, std::string b) : from(std::move(a)), to(std::move(b)) { fs::rename(from, to); }
  ~MovedAway() { fs::rename(to, from); }
};

test::GridScore export_and_score(const std::string& out, const std::string& grid_dir, test::CliRun& run) {
  run = test::run_gcmap("export " + out + " --grid -o " + grid_dir);
  if (run.code != 0) return {};
  const OccupancyGrid g = read_map_server(grid_dir + "/map.yaml");
  const Eigen::Matrix3d R = test::level_of(test::slurp(grid_dir + "/export.json"));
  const test::GridScore s = test::score_grid(g, SimulatedDriveExport::simulator(), 0.3f, 2.0f, R);
  std::printf(
      "grid %d x %d: IoU %.3f, occupied on a wall %.3f, %zu wall cells, %zu occupied, %zu free, %zu free inside, %zu deep\n",
      g.width, g.height, s.iou, s.occupied_on_wall, s.walls, s.occupied, s.free, s.free_inside, s.free_deep);
  return s;
}

TEST_F(SimulatedDriveExport, GridFromTheScansMatchesTheSimulatorsWalls) {
  test::CliRun run;
  const test::GridScore s = export_and_score(*dir / "out", *dir / "grid", run);
  ASSERT_EQ(run.code, 0) << run.err;
  EXPECT_NE(run.err.find("rays: the " + std::to_string(kFrames) + " scans of"), std::string::npos) << run.err;
  EXPECT_NE(run.err.find("Wrote " + (*dir / "grid") + ": map.pgm, map.yaml, export.json."), std::string::npos) << run.err;
  EXPECT_GT(s.walls, 2000u);
  EXPECT_GT(s.iou, 0.5);
  EXPECT_GT(s.occupied_on_wall, 0.8);
  EXPECT_LT(s.free_deep, s.free / 10000);  // no ray goes through a building
}

TEST_F(SimulatedDriveExport, GridFromTheSessionWhenTheScansAreGone) {
  const MovedAway gone(*dir / "sim", *dir / "sim_moved");
  test::CliRun run;
  const test::GridScore s = export_and_score(*dir / "out", *dir / "grid_session", run);
  ASSERT_EQ(run.code, 0) << run.err;
  EXPECT_NE(run.err.find("the scans it was mapped from are not on disk"), std::string::npos) << run.err;
  EXPECT_NE(run.err.find("rays: the submap clouds of"), std::string::npos) << run.err;
  EXPECT_GT(s.iou, 0.5);
  EXPECT_LT(s.free_deep, s.free / 1000);
}

// x y z intensity time, float32 each, of a binary little-endian PLY as gcmap writes it.
std::vector<std::array<float, 5>> read_ply_xyzit(const std::string& path) {
  const std::string bytes = test::slurp(path);
  const size_t body = bytes.find("end_header\n") + 11;
  EXPECT_NE(bytes.find("property float intensity\nproperty float time\nend_header"), std::string::npos) << path;
  std::vector<std::array<float, 5>> rows((bytes.size() - body) / 20);
  std::memcpy(rows.data(), bytes.data() + body, rows.size() * 20);
  return rows;
}

// Scan `frame` as the pipeline read it: sensor frame, intensities, times.
PointCloud recorded_scan(const std::string& sim_dir, int frame) {
  FolderScanSource source(sim_dir);
  for (int k = 0; k < frame; ++k) source.next();
  return source.next()->load();
}

TEST_F(SimulatedDriveExport, PerScanLasHoldsEachScanWhereTheSimulatorPutItWithItsAttributes) {
  const auto run = test::run_gcmap("export " + (*dir / "out") + " --per-scan -o " + (*dir / "scans_las"));
  ASSERT_EQ(run.code, 0) << run.err;
  EXPECT_NE(run.err.find("Exported " + std::to_string(kFrames) + " scans"), std::string::npos) << run.err;
  constexpr int kFrame = 35;  // under way: about half a metre of motion within the sweep
  const LasFile f = read_las(*dir / "scans_las/scans/000035.las");
  const PointCloud scan = recorded_scan(*dir / "sim", kFrame);
  ASSERT_EQ(f.cloud.size(), scan.size());
  ASSERT_TRUE(scan.has_times());
  const Trajectory t = read_trajectory(*dir / "out/trajectory.tum");
  EXPECT_EQ(read_trajectory(*dir / "scans_las/poses.tum").stamps, t.stamps);
  // Truth: each point from the simulator's pose at its firing time, in the map frame (frame 0).
  const sim::Simulator sim = simulator();
  const Eigen::Isometry3d T_map_world = sim.poses()[0].inverse();
  std::vector<double> error, error_at_stamp;
  for (size_t i = 0; i < scan.size(); ++i) {
    const Eigen::Vector3d p = scan.points[i].cast<double>();
    const Eigen::Vector3d truth = T_map_world * sim.pose_at(kFrame, scan.times[i]) * p;
    error.push_back((f.cloud.points[i] - truth).norm());
    error_at_stamp.push_back((t.poses[kFrame] * p - truth).norm());  // without the per-point pose
    ASSERT_NEAR(f.cloud.gps_times[i], t.stamps[kFrame] + scan.times[i], 1e-6);
    ASSERT_EQ(f.cloud.intensities[i], static_cast<uint16_t>(std::lround(scan.intensities[i] * 65535.0)));
    ASSERT_EQ(f.cloud.point_source_ids[i], kFrame);
  }
  std::sort(error.begin(), error.end());
  std::sort(error_at_stamp.begin(), error_at_stamp.end());
  const size_t median = error.size() / 2, p95 = error.size() * 95 / 100;
  EXPECT_LT(error[median], 0.05);
  EXPECT_LT(error[p95], 0.12);
  EXPECT_LT(error[p95], 0.5 * error_at_stamp[p95]);  // the motion within the sweep is accounted for
}

TEST_F(SimulatedDriveExport, PerScanPlyMatchesTheLasAndKeepsIntensityAndTime) {
  ASSERT_EQ(test::run_gcmap("export " + (*dir / "out") + " --per-scan --format ply -o " + (*dir / "scans_ply")).code, 0);
  ASSERT_EQ(test::run_gcmap("export " + (*dir / "out") + " --per-scan -o " + (*dir / "scans_las2")).code, 0);
  const auto ply = read_ply_xyzit(*dir / "scans_ply/scans/000003.ply");
  const LasFile las = read_las(*dir / "scans_las2/scans/000003.las");
  const PointCloud scan = recorded_scan(*dir / "sim", 3);
  ASSERT_EQ(ply.size(), scan.size());
  ASSERT_EQ(las.cloud.size(), scan.size());
  const double stamp = read_trajectory(*dir / "out/trajectory.tum").stamps[3];
  for (size_t i = 0; i < scan.size(); ++i) {
    ASSERT_LT((Eigen::Vector3d(ply[i][0], ply[i][1], ply[i][2]) - las.cloud.points[i]).norm(), 2e-3);
    ASSERT_EQ(ply[i][3], scan.intensities[i]);
    ASSERT_EQ(ply[i][4], scan.times[i]);
    ASSERT_NEAR(las.cloud.gps_times[i] - stamp, scan.times[i], 1e-6);
  }
}

TEST_F(SimulatedDriveExport, PerScanNeedsTheScansAndFindsThemWithScans) {
  const MovedAway gone(*dir / "sim", *dir / "sim_moved");
  const auto r = test::run_gcmap("export " + (*dir / "out") + " --per-scan -o " + (*dir / "x"));
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find((*dir / "out") + ": the scans it was mapped from are not on disk"), std::string::npos) << r.err;
  const auto moved = test::run_gcmap("export " + (*dir / "out") + " --per-scan --scans " + (*dir / "sim_moved") + " -o " +
                                     (*dir / "x") + " --quiet");
  EXPECT_EQ(moved.code, 0) << moved.err;
  EXPECT_EQ(read_las(*dir / "x/scans/000000.las").cloud.size(), recorded_scan(*dir / "sim_moved", 0).size());
  // Another recording: its stamps do not match the trajectory's.
  const auto other = test::run_gcmap("simulate --scenario small --frames 5 --seed 3 -o " + (*dir / "other"));
  ASSERT_EQ(other.code, 0) << other.err;
  std::ofstream(*dir / "other/times.txt") << "100.0\n100.1\n100.2\n100.3\n100.4\n";
  const auto wrong =
      test::run_gcmap("export " + (*dir / "out") + " --per-scan --scans " + (*dir / "other") + " -o " + (*dir / "y"));
  EXPECT_EQ(wrong.code, 2);
  EXPECT_NE(wrong.err.find("not the recording this map was made from"), std::string::npos) << wrong.err;
}

TEST(GridExport, OptionsAreCheckedBeforeAnythingIsRead) {
  test::TempDir tmp;
  for (const auto& [args, message] :
       std::vector<std::pair<std::string, std::string>>{{"--grid --grid-height 2,1", "--grid-height: MIN must be below MAX"},
                                                        {"--grid --grid-height 1", "--grid-height: expected MIN,MAX"},
                                                        {"--grid --grid-resolution 0", "--grid-resolution: expected (0, 10] m"},
                                                        {"--grid --per-scan", "--grid and --per-scan: one export at a time"},
                                                        {"--grid --origin 49,8,100", "--grid: the grid is in the map frame"}}) {
    const auto r = test::run_gcmap("export " + tmp.path.string() + " -o " + (tmp / "z") + " " + args);
    EXPECT_EQ(r.code, 2) << args;
    EXPECT_NE(r.err.find(message), std::string::npos) << args << ": " << r.err;
  }
}

// The figure for the closing note of issue #44, too slow for every run: a 600-frame city drive with
// all of its realism (traffic, noise, dropouts, stray echoes). GCMAP_CITY_GRID=DIR reuses DIR/sim and
// DIR/out. The mapped poses' few centimetres of error count against walls scored at 5 cm cells: the
// simulator's true poses in DIR/out/trajectory.tum score IoU 0.478 where the mapped ones score 0.272.
TEST(CityDriveGrid, DISABLED_GridMatchesTheSimulatorsWalls) {
  test::TempDir tmp;
  const char* given = std::getenv("GCMAP_CITY_GRID");
  const std::string dir = given ? given : tmp.path.string();
  if (!given) {
    ASSERT_EQ(test::run_gcmap("simulate --scenario city --frames 600 -o " + dir + "/sim").code, 0);
    ASSERT_EQ(test::run_gcmap("map " + dir + "/sim -o " + dir + "/out --device cpu --no-render --quiet").code, 0);
  }
  const auto run = test::run_gcmap("export " + dir + "/out --grid -o " + dir + "/grid");
  ASSERT_EQ(run.code, 0) << run.err;
  std::printf("%s", run.err.c_str());
  sim::SimulationConfig c;
  c.scenario = "city";
  c.frames = 600;
  const Eigen::Matrix3d R = test::level_of(test::slurp(dir + "/grid/export.json"));
  std::printf("levelled by %.4f deg\n", Eigen::AngleAxisd(R).angle() * 180.0 / M_PI);
  const test::GridScore s = test::score_grid(read_map_server(dir + "/grid/map.yaml"), sim::Simulator(c), 0.3f, 2.0f, R);
  std::printf("city: IoU %.3f, occupied on a wall %.3f, %zu wall cells, %zu occupied, %zu free, %zu free inside, %zu deep\n",
              s.iou, s.occupied_on_wall, s.walls, s.occupied, s.free, s.free_inside, s.free_deep);
  EXPECT_GT(s.iou, 0.25);
  EXPECT_GT(s.occupied_on_wall, 0.4);
  EXPECT_LT(s.free_deep, s.free / 1000);
}

}  // namespace
}  // namespace gcmap
