// GNSS end to end: simulated fixes on the small block loop, mapped with them, the UTM trajectory
// against the simulator's truth; and the simulated receiver against its own stated model.
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>

#include "gcmap/io/gnss_io.hpp"
#include "gcmap/io/las.hpp"
#include "gcmap/io/trajectory_io.hpp"
#include "test_util.hpp"

namespace gcmap {
namespace {

const Geodetic kOrigin{48.137154, 11.576124, 520.0};
const std::string kOriginArg = "--gnss-origin 48.137154,11.576124,520";

// The number after "key": in JSON text (first occurrence); NaN when absent.
double json_number(const std::string& text, const std::string& key) {
  const size_t at = text.find("\"" + key + "\":");
  if (at == std::string::npos) return std::nan("");
  return std::strtod(text.c_str() + at + key.size() + 3, nullptr);
}

// The simulator's sensor positions (poses_world.txt: local ENU at kOrigin) in UTM.
std::vector<Eigen::Vector3d> truth_utm(const std::string& sim_dir) {
  const Trajectory truth = read_trajectory(sim_dir + "/poses_world.txt");
  const CrsTransform utm(utm_epsg(kOrigin));
  std::vector<Eigen::Vector3d> out;
  for (const Eigen::Isometry3d& T : truth.poses) out.push_back(utm.from_ecef(T_ecef_enu(kOrigin) * T.translation()));
  return out;
}

struct Drive {
  test::TempDir dir;
  test::CliRun map;
  std::string stats;
  std::vector<Eigen::Vector3d> error;  // per frame: mapped UTM position - truth
};

// Simulates the small scenario's loop in `frames` frames with `gnss_args`, maps it with `config`
// (at 70 frames, 24 m/s, the odometry fails in a corner and the fixes cannot mend the map). With
// `bag`, scans and fixes come from an MCAP bag's /points and /gnss (NavSatFix) topics alone.
std::unique_ptr<Drive> map_drive(int frames, const std::string& gnss_args, const std::string& config, bool bag = false) {
  auto d = std::make_unique<Drive>();
  const test::CliRun sim =
      test::run_gcmap("simulate --scenario small --frames " + std::to_string(frames) + " --gnss " + kOriginArg + " " + gnss_args +
                      (bag ? " --format mcap" : "") + " -o " + (d->dir / "sim"));
  EXPECT_EQ(sim.code, 0) << sim.err;
  if (bag) std::filesystem::remove(d->dir / "sim/gnss.txt");
  std::ofstream(d->dir / "config.yaml") << config;
  const std::string input = d->dir / (bag ? "sim/drive.mcap" : "sim");
  d->map = test::run_gcmap("map " + input + " -o " + (d->dir / "out") + " --config " + (d->dir / "config.yaml") +
                           " --quiet --no-render");
  EXPECT_EQ(d->map.code, 0) << d->map.err;
  d->stats = test::slurp(d->dir / "out/stats.json");
  const std::vector<Eigen::Vector3d> truth = truth_utm(d->dir / "sim");
  const Trajectory mapped = read_trajectory(d->dir / "out/trajectory_utm.txt");
  EXPECT_EQ(mapped.size(), truth.size());
  for (size_t k = 0; k < std::min(mapped.size(), truth.size()); ++k) d->error.push_back(mapped.poses[k].translation() - truth[k]);
  return d;
}

double rms(const std::vector<Eigen::Vector3d>& e) {
  double s = 0.0;
  for (const Eigen::Vector3d& x : e) s += x.squaredNorm();
  return std::sqrt(s / std::max<size_t>(e.size(), 1));
}

// RTK at 10 Hz with an antenna 0.6 m above and off the LiDAR, 5 % multipath outliers and 3 s
// without fixes, all from a bag's NavSatFix topic: the UTM trajectory stays within centimetres of
// the truth throughout, the outage is bridged by the LiDAR without a jump, and the outliers are
// the fixes counted as rejected.
TEST(GnssDrive, RtkWithLeverArmOutliersAndOutageIsCentimetreAccurate) {
  const auto d = map_drive(100, "--gnss-lever-arm 0.3,-0.2,0.6 --gnss-outliers 0.05 --gnss-outage 4,7",
                           "gnss:\n  lever_arm_x: 0.3\n  lever_arm_y: -0.2\n  lever_arm_z: 0.6\n", true);
  ASSERT_FALSE(d->error.empty());
  EXPECT_NE(d->stats.find("\"georeferenced\":true"), std::string::npos) << d->stats;
  // The topic was found by itself, and the 30 NO_FIX epochs of the outage were skipped.
  EXPECT_NE(d->stats.find("drive.mcap: topic /gnss"), std::string::npos) << d->stats;
  EXPECT_NE(d->stats.find("30 epochs without a fix skipped"), std::string::npos) << d->stats;
  EXPECT_NE(d->map.err.find("GNSS: "), std::string::npos) << d->map.err;
  EXPECT_LT(rms(d->error), 0.08);
  double worst_step = 0.0;
  for (size_t k = 1; k < d->error.size(); ++k) worst_step = std::max(worst_step, (d->error[k] - d->error[k - 1]).norm());
  EXPECT_LT(worst_step, 0.05) << "a jump in the error between consecutive frames";
  const std::string sim = test::slurp(d->dir / "sim/scenario.json");
  const double outliers = json_number(sim, "outliers"), rejected = json_number(d->stats, "rejected");
  EXPECT_GT(outliers, 0);
  EXPECT_GE(rejected, outliers - 1);  // one may fall in a place where no fix is used
  EXPECT_LE(rejected, outliers + 2);
  EXPECT_GT(json_number(d->stats, "used"), 0.8 * json_number(sim, "fixes"));

  // export takes the run's ENU origin by itself: its UTM trajectory is the run's, the LAS coloured.
  const test::CliRun ex = test::run_gcmap("export " + (d->dir / "out") + " -o " + (d->dir / "las") + " --crs utm --color height");
  ASSERT_EQ(ex.code, 0) << ex.err;
  EXPECT_NE(test::slurp(d->dir / "las/export.json").find("from the run's GNSS (stats.json gnss.enu_origin)"), std::string::npos);
  const Trajectory run_utm = read_trajectory(d->dir / "out/trajectory_utm.txt");
  const Trajectory exported = read_trajectory(d->dir / "las/trajectory_utm32N.tum");
  ASSERT_EQ(exported.size(), run_utm.size());
  for (size_t k = 0; k < run_utm.size(); ++k)
    EXPECT_LT((exported.poses[k].translation() - run_utm.poses[k].translation()).norm(), 1e-3) << "frame " << k;
  const LasFile las = read_las(d->dir / "las/map.las");
  EXPECT_EQ(las.header.point_format, 7);
  EXPECT_EQ(las.cloud.colors.size(), las.cloud.size());
  EXPECT_NEAR(las.cloud.points.front().y(), run_utm.poses.front().translation().y(), 200.0);  // northings, not map metres
}

// Single-point fixes (2 m, correlated over 30 s) still georeference the map to metres.
TEST(GnssDrive, SinglePointFixesGeoreferenceToMetres) {
  const auto d = map_drive(100, "--gnss-quality single", "");
  ASSERT_FALSE(d->error.empty());
  EXPECT_NE(d->stats.find("\"georeferenced\":true"), std::string::npos);
  EXPECT_LT(rms(d->error), 5.0);
}

TEST(GnssInput, ABadLineStopsTheRunNamingFileAndLine) {
  test::TempDir dir;
  ASSERT_EQ(test::run_gcmap("simulate --scenario small --frames 3 -o " + (dir / "sim")).code, 0);
  std::ofstream(dir / "sim/gnss.txt") << "# fixes\n0 48 11 500 0.1 0.1 0.2\n0.1 48 11 500 0.1 0.1\n";
  const test::CliRun r = test::run_gcmap("map " + (dir / "sim") + " -o " + (dir / "out") + " --quiet --no-render");
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.err.find("gnss.txt:3: 6 values, expected 7"), std::string::npos) << r.err;
  const test::CliRun missing = test::run_gcmap("map " + (dir / "sim") + " -o " + (dir / "out") + " --gnss " + (dir / "none.txt"));
  EXPECT_NE(missing.code, 0);
  EXPECT_NE(missing.err.find("none.txt: --gnss: no such file"), std::string::npos) << missing.err;
  const test::CliRun topic = test::run_gcmap("map " + (dir / "sim") + " -o " + (dir / "out") + " --gnss-topic /fix");
  EXPECT_NE(topic.code, 0);
  EXPECT_NE(topic.err.find("--gnss-topic: the input is not a bag"), std::string::npos) << topic.err;
}

}  // namespace
}  // namespace gcmap
