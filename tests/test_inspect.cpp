// What gcmap assumes about a recording (decide_input) and what `gcmap inspect` reports, on inputs the
// simulator writes (every per-point time convention, and each usual mistake) and on small folders.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>

#include "gcmap/core/error.hpp"
#include "gcmap/io/inspect.hpp"
#include "gcmap/io/point_cloud_io.hpp"
#include "gcmap/io/sequence.hpp"
#include "gcmap/sim/synthetic.hpp"
#include "test_util.hpp"

namespace gcmap::test {
namespace {

namespace fs = std::filesystem;

// A short drive with motion distortion only, so that points carry times (a 16-beam sensor unless told).
const std::string kSim = " --scenario city --frames 12 --seed 5 --realism motion_distortion";

std::string simulate(const TempDir& dir, const std::string& name, const std::string& args) {
  const std::string sensor = args.find("--sensor") == std::string::npos ? " --sensor vlp16" : "";
  const CliRun r = run_gcmap("simulate -o " + (dir / name) + kSim + sensor + " " + args);
  EXPECT_EQ(r.code, 0) << name << ": " << r.err;
  return dir / name;
}

std::string bag_of(const std::string& dir) {
  for (const char* name : {"drive.mcap", "drive.bag", "drive"})
    if (fs::exists(fs::path(dir) / name)) return (fs::path(dir) / name).string();
  return dir;
}

bool has_warning(const InspectReport& r, const std::string& text) {
  for (const std::string& w : r.warnings)
    if (w.find(text) != std::string::npos) return true;
  return false;
}

std::string all_warnings(const InspectReport& r) {
  std::string out;
  for (const std::string& w : r.warnings) out += w + "\n";
  return out;
}

void write_text(const std::string& path, const std::string& text) { std::ofstream(path) << text; }

// A folder of n small PCD scans.
void write_scans(const fs::path& dir, int n, const std::string& ext = ".pcd") {
  fs::create_directories(dir);
  for (int k = 0; k < n; ++k) {
    char name[32];
    std::snprintf(name, sizeof name, "%06d%s", k, ext.c_str());
    write_point_cloud((dir / name).string(), make_structured_scene(2000, k + 1));
  }
}

// A ring-ordered scan of 64 rings (as KITTI's .bin files are): each ring one turn in azimuth.
PointCloud ring_ordered_scan(int rings) {
  PointCloud c;
  for (int r = 0; r < rings; ++r) {
    const double el = (2.0 - 26.8 * r / (rings - 1)) * M_PI / 180.0;
    for (int a = 0; a < 720; ++a) {
      const double az = M_PI - 2 * M_PI * a / 720.0, range = 10.0 + 0.01 * a;
      c.points.emplace_back(range * std::cos(el) * std::cos(az), range * std::cos(el) * std::sin(az), range * std::sin(el));
      c.intensities.push_back(0.5f);
    }
  }
  return c;
}

TEST(InputAssumptions, TimesBesideTheScansFolderAreFound) {
  // hku1_livox's layout: scans/ with times.txt beside it, as KITTI keeps times.txt beside velodyne/.
  TempDir dir;
  write_scans(dir.path / "rec" / "scans", 3);
  write_text(dir / "rec/times.txt", "100.0\n100.4\n101.3\n");
  const InputAssumptions a = decide_input(dir / "rec/scans", {});
  EXPECT_EQ(a.stamp_source, StampSource::times_file);
  EXPECT_EQ(a.times_path, fs::absolute(dir.path / "rec/times.txt").lexically_normal().string());
  ASSERT_EQ(a.stamps.size(), 3u);
  EXPECT_DOUBLE_EQ(a.stamps[2], 101.3);
  FolderScanSource source(a, 1, 0);
  EXPECT_DOUBLE_EQ(source.next()->stamp, 100.4);
  EXPECT_TRUE(a.warnings.empty()) << a.warnings.front();
}

TEST(InputAssumptions, TimesOptionNamesTheFile) {
  TempDir dir;
  write_scans(dir.path / "scans", 2);
  write_text(dir / "t.txt", "5\n6\n");
  const InputAssumptions a = decide_input(dir / "scans", {.times_file = dir / "t.txt"});
  EXPECT_EQ(a.times_path, dir / "t.txt");
  EXPECT_DOUBLE_EQ(a.stamps[1], 6.0);
  EXPECT_THROW(decide_input(dir / "scans", {.times_file = dir / "absent.txt"}), Error);
}

TEST(InputAssumptions, TimesCountMismatchIsAnErrorNamingTheFile) {
  // Formerly the scans past the end of times.txt were stamped 0.1 x index (going backwards).
  TempDir dir;
  write_scans(dir.path / "scans", 3);
  write_text(dir / "scans/times.txt", "100.0\n100.1\n");
  try {
    decide_input(dir / "scans", {});
    ADD_FAILURE() << "accepted 2 stamps for 3 scans";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("times.txt: 2 stamps for 3 scans"), std::string::npos) << e.what();
  }
}

TEST(InputAssumptions, StampsGoingBackwardsAreAnError) {
  TempDir dir;
  write_scans(dir.path / "scans", 3);
  write_text(dir / "scans/times.txt", "1.0\n1.2\n1.1\n");
  try {
    decide_input(dir / "scans", {});
    ADD_FAILURE() << "accepted stamps going backwards";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("times.txt: line 3: stamp 1.100000 s is before the previous"), std::string::npos)
        << e.what();
  }
  write_text(dir / "scans/times.txt", "1.0\nabc\n1.1\n");
  EXPECT_THROW(decide_input(dir / "scans", {}), Error);
}

TEST(InputAssumptions, NoStampsGivesOneWarningWithTheAssumedRate) {
  TempDir dir;
  write_scans(dir.path / "scans", 3);
  const InputAssumptions a = decide_input(dir / "scans", {});
  EXPECT_EQ(a.stamp_source, StampSource::assumed_rate);
  ASSERT_EQ(a.warnings.size(), 1u);
  EXPECT_NE(a.warnings[0].find("no stamps: scans assumed 0.1 s apart"), std::string::npos) << a.warnings[0];
  EXPECT_NE(a.warnings[0].find("--times"), std::string::npos);
  EXPECT_DOUBLE_EQ(a.stamps[2], 0.2);
}

TEST(InputAssumptions, PcdUnderVelodyneGetsNoKittiCorrection) {
  TempDir dir;
  write_scans(dir.path / "seq" / "velodyne", 2, ".pcd");
  write_text(dir / "seq/times.txt", "0\n0.1\n");
  const InputAssumptions a = decide_input(dir / "seq", {});
  EXPECT_EQ(a.layout, InputLayout::kitti);
  EXPECT_FALSE(a.kitti_correction);
  EXPECT_EQ(a.elevation_correction.value, "none");
  EXPECT_NE(a.elevation_correction.evidence.find("not KITTI's .bin"), std::string::npos) << a.elevation_correction.evidence;
  EXPECT_FALSE(FolderScanSource(a, 0, 0).kitti_hdl64());
}

TEST(InputAssumptions, KittiCorrectionNeedsAllOfKittisEvidence) {
  TempDir dir;
  fs::create_directories(dir.path / "seq" / "velodyne");
  write_bin(dir / "seq/velodyne/000000.bin", ring_ordered_scan(64));
  // velodyne/ and .bin alone: no calib.txt or times.txt beside it.
  EXPECT_FALSE(decide_input(dir / "seq", {}).kitti_correction);
  write_text(dir / "seq/calib.txt", "Tr: 1 0 0 0 0 1 0 0 0 0 1 0\n");
  const InputAssumptions a = decide_input(dir / "seq", {});
  EXPECT_TRUE(a.kitti_correction) << a.elevation_correction.evidence;
  EXPECT_NE(a.elevation_correction.evidence.find("64 rings"), std::string::npos) << a.elevation_correction.evidence;
  // The same seen from inside velodyne/.
  EXPECT_TRUE(decide_input(dir / "seq/velodyne", {}).kitti_correction);
  EXPECT_FALSE(decide_input(dir / "seq", {.kitti_vertical_correction = false}).kitti_correction);
  // A 32-ring sensor in KITTI's layout is not KITTI's HDL-64.
  write_bin(dir / "seq/velodyne/000000.bin", ring_ordered_scan(32));
  EXPECT_NE(decide_input(dir / "seq", {}).elevation_correction.evidence.find("32 rings"), std::string::npos);
  write_bin(dir / "seq/velodyne/000000.bin", ring_ordered_scan(64));
  write_text(dir / "seq/scenario.json", "{}\n");
  EXPECT_FALSE(decide_input(dir / "seq", {}).kitti_correction);
}

TEST(InputAssumptions, SimulatedKittiLayoutIsNotCorrected) {
  TempDir dir;
  const InputAssumptions a = decide_input(simulate(dir, "kitti", "--sensor hdl64"), {});
  EXPECT_FALSE(a.kitti_correction);
  EXPECT_NE(a.elevation_correction.evidence.find("scenario.json"), std::string::npos) << a.elevation_correction.evidence;
  EXPECT_TRUE(a.point_times);
  EXPECT_EQ(a.deskew.value, "on");
  EXPECT_EQ(a.to_json().dump().find("\"kitti_elevation_correction\":false") != std::string::npos, true);
}

TEST(InputAssumptions, ASequenceFolderNamedVelodyneKeepsItsSidecars) {
  // `gcmap simulate -o run/velodyne` writes the sequence into a folder named velodyne (its scans in
  // velodyne/velodyne/): its point times lie beside its scans folder, not one level up.
  TempDir dir;
  const std::string seq = simulate(dir, "velodyne", "");
  const InputAssumptions a = decide_input(seq, {});
  EXPECT_EQ(fs::path(a.root), fs::path(seq));
  EXPECT_TRUE(a.point_times) << a.point_times_text.evidence;
  EXPECT_EQ(a.deskew.value, "on");
  // Its scans folder given itself still finds the sequence folder as its parent.
  EXPECT_EQ(fs::path(decide_input(seq + "/velodyne", {}).root), fs::path(seq));
}

TEST(Inspect, EveryTimeConventionReadsCleanly) {
  TempDir dir;
  for (const std::string& field : {"ouster", "velodyne", "hesai", "livox"}) {
    const std::string bag = bag_of(simulate(dir, field, "--format mcap --time-field " + field));
    const InspectReport r = inspect_recording(bag, {});
    SCOPED_TRACE(field);
    EXPECT_EQ(r.stamps, 12u);
    EXPECT_NEAR(r.rate_hz, 10.0, 0.01);
    EXPECT_EQ(r.assumptions.stamp_source, StampSource::point_times);
    EXPECT_NEAR(r.time_min, 0.0, 1e-3);
    EXPECT_NEAR(r.time_max, 0.1, 0.005);
    EXPECT_NEAR(r.sweep_period, 0.1, 0.01);
    EXPECT_NE(r.sweep_direction, "none");
    EXPECT_EQ(r.shape.rings, 16);
    EXPECT_TRUE(r.shape.spinning);
    EXPECT_FALSE(r.assumptions.kitti_correction);
    EXPECT_TRUE(r.warnings.empty()) << all_warnings(r);
  }
}

TEST(Inspect, EachTimeMistakeIsNamed) {
  TempDir dir;
  const std::vector<std::pair<std::string, std::string>> cases = {{"ms", "milliseconds where seconds"},
                                                                  {"ns", "nanoseconds where seconds"},
                                                                  {"absolute", "absolute times"},
                                                                  {"sweep_end", "stamps the end of the sweep"},
                                                                  {"zero", "all zero"}};
  for (const auto& [mistake, text] : cases) {
    for (const std::string& format : {"kitti", "mcap"}) {
      SCOPED_TRACE(mistake + " " + format);
      const std::string out =
          simulate(dir, mistake + format,
                   "--format " + format + (format == "kitti" ? "" : " --time-field velodyne") + " --time-mistake " + mistake);
      const InspectReport r = inspect_recording(format == "kitti" ? out : bag_of(out), {});
      EXPECT_TRUE(has_warning(r, text)) << all_warnings(r);
      // decide_input (what `map` states) sees it in the first scan too.
      EXPECT_FALSE(r.assumptions.warnings.empty()) << mistake;
    }
  }
}

TEST(Inspect, SensorShapes) {
  TempDir dir;
  const InspectReport hdl = inspect_recording(simulate(dir, "hdl", "--sensor hdl64"), {});
  EXPECT_EQ(hdl.shape.rings, 64) << hdl.shape.ring_evidence;
  EXPECT_TRUE(hdl.shape.spinning);
  EXPECT_LT(hdl.shape.elevation_min_deg, -20.0);
  const InspectReport avia = inspect_recording(simulate(dir, "avia", "--sensor avia"), {});
  EXPECT_EQ(avia.shape.rings, 0) << avia.shape.ring_evidence;
  EXPECT_FALSE(avia.shape.spinning);
  EXPECT_EQ(avia.to_json().dump().find("\"pattern\":\"non-repetitive\"") != std::string::npos, true) << avia.to_json().dump();
}

TEST(Inspect, CountsNanAndZeroPoints) {
  TempDir dir;
  fs::create_directories(dir.path / "scans");
  PointCloud c = make_structured_scene(1000, 1);
  c.points[0] = Eigen::Vector3f(NAN, 0, 0);
  c.points[1] = Eigen::Vector3f::Zero();
  c.points[2] = Eigen::Vector3f::Zero();
  write_bin(dir / "scans/000000.bin", c);
  const InspectReport r = inspect_recording(dir / "scans", {});
  EXPECT_EQ(r.nan_points, 1u);
  EXPECT_EQ(r.zero_points, 2u);
  EXPECT_EQ(r.points_max, 997u);
}

TEST(Inspect, Hku1LivoxLayout) {
  GCMAP_REQUIRE_SHARED_DATA("hku1_livox");
  const InspectReport r = inspect_recording(shared_data() + "/hku1_livox/scans", {});
  EXPECT_EQ(r.assumptions.stamp_source, StampSource::times_file);
  EXPECT_EQ(r.stamps, 314u);
  EXPECT_FALSE(r.assumptions.kitti_correction);
  EXPECT_FALSE(r.shape.spinning);
}

TEST(InspectCli, HumanAndJson) {
  TempDir dir;
  const std::string seq = simulate(dir, "kitti", "");
  const CliRun text = run_gcmap("inspect " + seq);
  ASSERT_EQ(text.code, 0) << text.err;
  for (const char* key :
       {"stamps: 12, times file", "per-point times:", "16 rings", "gcmap map will assume:", "elevation correction: none"})
    EXPECT_NE(text.out.find(key), std::string::npos) << key << " in\n" << text.out;
  const CliRun json = run_gcmap("inspect --json " + seq);
  ASSERT_EQ(json.code, 0) << json.err;
  for (const char* key : {"\"assumptions\":{", "\"stamps\":{\"count\":12", "\"rings\":16", "\"sweep_period_s\":"})
    EXPECT_NE(json.out.find(key), std::string::npos) << key << " in\n" << json.out;
  const CliRun missing = run_gcmap("inspect " + (dir / "absent"));
  EXPECT_EQ(missing.code, 2);
  EXPECT_NE(missing.err.find("absent: not a folder"), std::string::npos) << missing.err;
}

// A folder of identical scans of one scene (the sensor stands still), stamped 0.1 s apart.
std::string still_scans(const TempDir& dir, int n, BinFields fields = BinFields::xyzi) {
  fs::create_directories(dir.path / "scans");
  const PointCloud c = make_structured_scene(20001, 3);  // 20001 x 12 bytes is no multiple of 16
  std::string times;
  for (int k = 0; k < n; ++k) {
    write_bin(dir / ("scans/00000" + std::to_string(k) + ".bin"), c, fields);
    times += std::to_string(0.1 * k) + "\n";
  }
  write_text(dir / "times.txt", times);
  return dir / "scans";
}

TEST(MapCli, StatesItsAssumptionsAndWritesThemToStats) {
  TempDir dir;
  const std::string scans = still_scans(dir, 4);
  const CliRun r = run_gcmap("map " + scans + " -o " + (dir / "out") + " --no-render");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.err.find("stamps: times file ("), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("elevation correction: none (not the KITTI layout"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("deskewing: off (the scans carry no per-point times)"), std::string::npos) << r.err;
  const std::string stats = slurp(dir / "out/stats.json");
  for (const char* key : {"\"assumptions\":{", "\"stamp_source\":\"times_file\"", "\"kitti_elevation_correction\":false"})
    EXPECT_NE(stats.find(key), std::string::npos) << key;
}

TEST(MapCli, UnreadableScansExitNonZero) {
  TempDir dir;
  fs::create_directories(dir.path / "scans");
  for (int k = 0; k < 4; ++k) write_text(dir / ("scans/00000" + std::to_string(k) + ".bin"), "not a scan");
  const CliRun r = run_gcmap("map " + (dir / "scans") + " -o " + (dir / "out") + " --quiet --no-render");
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_NE(r.err.find("none of its 4 scans could be mapped"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir / "out/map.ply"));
}

TEST(MapCli, MostScansUnusableExitsNonZeroAfterWriting) {
  TempDir dir;
  const std::string scans = still_scans(dir, 4);
  for (int k = 1; k < 4; ++k) write_text(dir / ("scans/00000" + std::to_string(k) + ".bin"), "not a scan");
  const CliRun r = run_gcmap("map " + scans + " -o " + (dir / "out") + " --quiet --no-render");
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_NE(r.err.find("3 of its 4 scans could not be mapped"), std::string::npos) << r.err;
  EXPECT_TRUE(fs::exists(dir / "out/stats.json"));
}

TEST(MapCli, BinFieldsXyz) {
  TempDir dir;
  const std::string scans = still_scans(dir, 3, BinFields::xyz);
  const CliRun wrong = run_gcmap("map " + scans + " -o " + (dir / "a") + " --quiet --no-render");
  EXPECT_EQ(wrong.code, 2) << wrong.err;
  EXPECT_NE(wrong.err.find("--bin-fields"), std::string::npos) << wrong.err;
  const CliRun right = run_gcmap("map " + scans + " -o " + (dir / "b") + " --quiet --no-render --bin-fields xyz");
  EXPECT_EQ(right.code, 0) << right.err;
  const CliRun bad = run_gcmap("map " + scans + " -o " + (dir / "c") + " --bin-fields xyzw");
  EXPECT_EQ(bad.code, 2);
  EXPECT_NE(bad.err.find("--bin-fields: expected xyz or xyzi"), std::string::npos) << bad.err;
}

TEST(MapCli, OutputInsideTheScansFolderIsRefused) {
  TempDir dir;
  const std::string scans = still_scans(dir, 2);
  for (const std::string& out : {scans, scans + "/", scans + "/out"}) {
    const CliRun r = run_gcmap("map " + scans + " -o " + out + " --quiet");
    EXPECT_EQ(r.code, 2) << out;
    EXPECT_NE(r.err.find("the output folder is the input's scans folder or inside it"), std::string::npos) << r.err;
  }
  fs::create_directories(dir.path / "seq");
  fs::rename(scans, dir.path / "seq" / "velodyne");
  const CliRun kitti = run_gcmap("map " + (dir / "seq") + " -o " + (dir / "seq/velodyne/out") + " --quiet");
  EXPECT_EQ(kitti.code, 2) << kitti.err;
  EXPECT_EQ(std::count(kitti.err.begin(), kitti.err.end(), '\n'), 1) << kitti.err;
  EXPECT_FALSE(fs::exists(dir / "seq/velodyne/out"));
}

TEST(MapCli, TimesOptionAndMismatch) {
  TempDir dir;
  const std::string scans = still_scans(dir, 3);
  write_text(dir / "short.txt", "0\n0.1\n");
  const CliRun r = run_gcmap("map " + scans + " -o " + (dir / "out") + " --quiet --times " + (dir / "short.txt"));
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("short.txt: 2 stamps for 3 scans"), std::string::npos) << r.err;
}

}  // namespace
}  // namespace gcmap::test
