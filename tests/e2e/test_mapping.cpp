// The mapping system end to end through the gcmap binary, on the simulator's small scenario.
#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <fstream>
#include <map>
#include <regex>

#include "gcmap/core/error.hpp"
#include "gcmap/eval/trajectory_metrics.hpp"
#include "gcmap/io/file.hpp"
#include "gcmap/io/point_cloud_io.hpp"
#include "gcmap/io/trajectory_io.hpp"
#include "gcmap/mapping/config.hpp"
#include "gcmap/odometry/preprocess_scan.hpp"
#include "gcmap/registration/registration.hpp"
#include "gcmap/session/session.hpp"
#include "gcmap/sim/simulator.hpp"
#include "test_util.hpp"

namespace gcmap {
namespace {

int run(const std::string& args, std::string* err = nullptr) {
  const std::string log = std::filesystem::temp_directory_path() / ("gcmap_map_test_" + std::to_string(::getpid()) + ".err");
  const int status = std::system((std::string(GCMAP_CLI) + " " + args + " >/dev/null 2>" + log).c_str());
  if (err) {
    std::ifstream in(log);
    *err = std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  }
  std::filesystem::remove(log);
  return WEXITSTATUS(status);
}

std::string slurp(const std::string& p) {
  std::ifstream in(p);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

class SmallScenario : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir = new test::TempDir();
    sim::SimulationConfig cfg;
    cfg.scenario = "small";
    sim::write_simulation(*dir / "sim", cfg);
  }
  static void TearDownTestSuite() { delete dir; }
  static test::TempDir* dir;
};
test::TempDir* SmallScenario::dir = nullptr;

TEST_F(SmallScenario, GlobalMappingIsAccurateAndClosesTheLoop) {
  std::string err;
  ASSERT_EQ(run("map " + (*dir / "sim") + " -o " + (*dir / "out") + " --quiet", &err), 0) << err;
  const Poses gt = read_trajectory(*dir / "sim/poses.txt").poses;
  const Poses est = read_trajectory(*dir / "out/trajectory.kitti").poses;
  const Poses odom = read_trajectory(*dir / "out/odometry.kitti").poses;
  ASSERT_EQ(est.size(), gt.size());  // one pose for every input frame
  ASSERT_EQ(odom.size(), gt.size());
  EXPECT_LT(test::translation_error(est.front(), Eigen::Isometry3d::Identity()), 1e-9);
  const double ate = absolute_trajectory_error(gt, est).rmse, ate_odom = absolute_trajectory_error(gt, odom).rmse;
  EXPECT_LT(ate, 0.10);
  EXPECT_LT(ate, ate_odom);
  EXPECT_EQ(read_trajectory(*dir / "out/trajectory.tum").size(), gt.size());
  EXPECT_GT(read_point_cloud(*dir / "out/map.ply").size(), 10000u);

  // Graph decisions are asserted through the library (test_pipeline.cpp); here the file is whole.
  const std::string graph = slurp(*dir / "out/graph.json");
  EXPECT_NE(graph.find("\"type\":\"matching_cost\""), std::string::npos);
  EXPECT_NE(graph.find("\"loop_candidates\":["), std::string::npos);
  EXPECT_EQ(graph.back(), '\n');
  for (const char* f : {"stats.json", "config.yaml", "odometry.kitti"})
    EXPECT_TRUE(std::filesystem::exists(*dir / ("out/" + std::string(f))));
  EXPECT_NE(slurp(*dir / "out/stats.json").find("\"global_optimization\":{\"mean_ms\":"), std::string::npos);
  EXPECT_NE(slurp(*dir / "out/stats.json").find("\"final_optimization_ms\":"), std::string::npos);
}

TEST_F(SmallScenario, CorruptScanInTheMiddleIsSkipped) {
  // A copy of the first 20 frames with frame 10 truncated.
  const std::string seq = *dir / "corrupt";
  std::filesystem::create_directories(seq + "/velodyne");
  for (int k = 0; k < 20; ++k) {
    char name[32];
    std::snprintf(name, sizeof(name), "/velodyne/%06d.bin", k);
    std::filesystem::copy_file(*dir / "sim" + name, seq + name);
    if (k == 10) std::filesystem::resize_file(seq + name, 1001);
  }
  std::string err;
  ASSERT_EQ(run("map " + seq + " -o " + (*dir / "corrupt_out") + " --quiet --no-explicit-loops", &err), 0) << err;
  EXPECT_NE(err.find("000010.bin"), std::string::npos) << err;
  EXPECT_EQ(read_trajectory(*dir / "corrupt_out/trajectory.kitti").size(), 20u);
  EXPECT_NE(slurp(*dir / "corrupt_out/config.yaml").find("loop:\n  enabled: false"), std::string::npos);
}

// `gcmap map SIM -o OUT ARGS` (stdout and stderr to `log`), sent SIGINT once it has spent a
// second of CPU time; its exit status.
int interrupted_map(const std::string& sim, const std::string& out, const std::string& log, const char* arg) {
  const pid_t pid = fork();
  if (pid == 0) {
    const int file = open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    dup2(file, 1);
    dup2(file, 2);
    execl(GCMAP_CLI, GCMAP_CLI, "map", sim.c_str(), "-o", out.c_str(), "--no-explicit-loops", "--no-render", arg, nullptr);
    _exit(127);
  }
  const auto cpu_ticks = [pid] {
    std::ifstream stat("/proc/" + std::to_string(pid) + "/stat");
    std::string field;
    long ticks = 0;
    for (int k = 1; k <= 15 && stat >> field; ++k)
      if (k == 14 || k == 15) ticks += std::stol(field);
    return ticks;
  };
  int status = 0;
  while (cpu_ticks() < sysconf(_SC_CLK_TCK) && waitpid(pid, &status, WNOHANG) == 0) usleep(20000);
  EXPECT_EQ(waitpid(pid, &status, WNOHANG), 0) << "the run ended before it could be interrupted";
  kill(pid, SIGINT);
  EXPECT_EQ(waitpid(pid, &status, 0), pid);
  EXPECT_TRUE(WIFEXITED(status));
  return WEXITSTATUS(status);
}

TEST_F(SmallScenario, InterruptionWritesPartialOutputs) {
  // SIGINT while the beam elevations are estimated, before any frame is mapped: exit 130, one line
  // saying so, nothing written.
  const std::string early = *dir / "interrupted_early";
  EXPECT_EQ(interrupted_map(*dir / "sim", early, *dir / "early.log", "--quiet"), 130);
  EXPECT_NE(slurp(*dir / "early.log").find("Interrupted while estimating the beam elevations: nothing mapped, nothing written."),
            std::string::npos)
      << slurp(*dir / "early.log");
  EXPECT_FALSE(std::filesystem::exists(early + "/stats.json"));
  // SIGINT once mapping is under way: exit 130, every output written for the frames mapped so far,
  // stats.json marked partial.
  const std::string out = *dir / "interrupted";
  EXPECT_EQ(interrupted_map(*dir / "sim", out, *dir / "late.log", "--no-elevation-estimate"), 130);
  const std::string stats = slurp(out + "/stats.json");
  EXPECT_NE(stats.find("\"partial\":true"), std::string::npos) << stats.substr(0, 300);
  EXPECT_NE(stats.find("\"interrupted_by\":\"SIGINT\""), std::string::npos);
  const size_t frames = read_trajectory(out + "/trajectory.kitti").size();
  EXPECT_GT(frames, 0u);
  EXPECT_LT(frames, read_trajectory(*dir / "sim/poses.txt").size());
  EXPECT_EQ(read_trajectory(out + "/odometry.kitti").size(), frames);
  EXPECT_GT(read_point_cloud(out + "/map.ply").size(), 0u);
}

// Every file below `dir` (relative path -> bytes), but the timings and peak memory of stats.json.
std::map<std::string, std::string> output_files(const std::string& dir) {
  std::map<std::string, std::string> files;
  for (const auto& e : std::filesystem::recursive_directory_iterator(dir))
    if (e.is_regular_file()) files[std::filesystem::relative(e.path(), dir).string()] = slurp(e.path());
  return files;
}

TEST_F(SmallScenario, FullDiskLeavesThePreviousOutputsWhole) {
  // A file-size limit on the child (RLIMIT_FSIZE through the shell's ulimit, in KiB) makes map.ply
  // fail to write: exit 2 naming it, and the outputs of the run before stay as they were.
  const std::string out = *dir / "full_disk";
  const std::string args = "map " + (*dir / "sim") + " -o " + out + " --quiet --no-explicit-loops --no-render --device cpu";
  std::string err;
  ASSERT_EQ(run(args + " --max-frames 20", &err), 0) << err;
  const auto before = output_files(out);
  ASSERT_GT(before.at("map.ply").size(), 200u * 1024) << "the limit below must cut map.ply";
  const std::string limited = "sh -c 'ulimit -f 200; exec " + std::string(GCMAP_CLI) + " " + args + " --max-frames 30' 2>";
  const std::string log = *dir / "full_disk.err";
  const int status = std::system((limited + log).c_str());
  err = slurp(log);
  EXPECT_EQ(WEXITSTATUS(status), 2) << err;
  EXPECT_NE(err.find(out + "/map.ply: write failed"), std::string::npos) << err;
  EXPECT_NE(err.find("previous outputs in " + out + " are unchanged"), std::string::npos) << err;
  EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << err;
  EXPECT_EQ(output_files(out), before) << "a file of the previous run changed, or a staging file was left";
}

// All values of `key` in the JSON text from `from` on, in order.
std::vector<int> json_ints(const std::string& json, const std::string& key, size_t from = 0) {
  std::vector<int> out;
  const std::regex re("\"" + key + "\":(-?[0-9]+)");
  for (auto it = std::sregex_iterator(json.begin() + from, json.end(), re); it != std::sregex_iterator(); ++it)
    out.push_back(std::stoi((*it)[1]));
  return out;
}

TEST_F(SmallScenario, QualityJsonNumbersFramesAsTheInputDoes) {
  // --start 30: the run's first frame is the input's 30th, in quality.json as in graph.json.
  std::string err;
  ASSERT_EQ(run("map " + (*dir / "sim") + " --quiet --no-render --start 30 --max-frames 40 -o " + (*dir / "start30"), &err), 0)
      << err;
  const std::string quality = slurp(*dir / "start30/quality.json"), graph = slurp(*dir / "start30/graph.json");
  const size_t frames = quality.find("\"frames\":["), submaps = quality.find("\"submaps\":[");
  ASSERT_NE(frames, std::string::npos);
  ASSERT_NE(submaps, std::string::npos);
  const std::vector<int> numbers = json_ints(quality.substr(frames, submaps - frames), "frame");
  ASSERT_EQ(numbers.size(), 40u);
  EXPECT_EQ(numbers.front(), 30);
  EXPECT_EQ(numbers.back(), 69);
  const std::vector<int> first = json_ints(quality, "first_frame", submaps);
  ASSERT_GE(first.size(), 2u);
  EXPECT_EQ(first.front(), 30);
  EXPECT_EQ(first, json_ints(graph, "first_frame"));
  EXPECT_EQ(json_ints(quality, "last_frame", submaps), json_ints(graph, "last_frame"));
}

TEST_F(SmallScenario, SameInputGivesByteIdenticalOutputs) {
  // Same input, config and threads: every output byte-identical (stats.json holds timings and is
  // left out). One and two threads: the same trajectory, since every parallel sum is reduced in a
  // fixed order whatever the thread count.
  const std::string args = "map " + (*dir / "sim") + " --quiet --max-frames 60 -o ";
  std::string err;
  for (const char* run_name : {"det_a", "det_b"}) ASSERT_EQ(run(args + (*dir / run_name) + " --threads 2", &err), 0) << err;
  ASSERT_EQ(run(args + (*dir / "det_1") + " --threads 1", &err), 0) << err;
  auto a = output_files(*dir / "det_a"), b = output_files(*dir / "det_b"), one = output_files(*dir / "det_1");
  for (auto* files : {&a, &b, &one}) ASSERT_EQ(files->erase("stats.json"), 1u);
  EXPECT_GE(a.size(), 10u);  // trajectories, map, graph, config, map.png, the session's files
  EXPECT_EQ(a, b);
  const Poses pa = read_trajectory(*dir / "det_a/trajectory.kitti").poses;
  const Poses p1 = read_trajectory(*dir / "det_1/trajectory.kitti").poses;
  ASSERT_EQ(pa.size(), p1.size());
  for (size_t k = 0; k < pa.size(); ++k) EXPECT_LT(test::translation_error(pa[k], p1[k]), 1e-9) << "frame " << k;
  EXPECT_EQ(a, one);
}

TEST(Mapping, BadInputGivesOneLineErrors) {
  test::TempDir dir;
  std::filesystem::create_directories(dir / "empty");
  std::string err;
  EXPECT_EQ(run("map " + (dir / "empty") + " -o " + (dir / "out"), &err), 2);
  EXPECT_NE(err.find("no .bin, .pcd or .ply scans"), std::string::npos) << err;
  // A recording's export, times.txt beside its scans' folder: the error names that folder.
  std::filesystem::create_directories(dir / "export/scans");
  for (const std::string name : {"000000.pcd", "000001.pcd"}) std::ofstream(dir / ("export/scans/" + name)) << "";
  EXPECT_EQ(run("map " + (dir / "export") + " -o " + (dir / "out"), &err), 2);
  EXPECT_NE(err.find("no .bin, .pcd or .ply scans (" + (dir / "export/scans") + " holds 2 scans: give that folder)"),
            std::string::npos)
      << err;

  std::ofstream(dir / "bad.yaml") << "local:\n  th_maxx: 0.9\n";
  EXPECT_EQ(run("config --config " + (dir / "bad.yaml"), &err), 2);
  EXPECT_NE(err.find("unknown key 'local.th_maxx'"), std::string::npos) << err;
  std::ofstream(dir / "bad2.yaml") << "global:\n  th_min: banana\n";
  EXPECT_EQ(run("config --config " + (dir / "bad2.yaml"), &err), 2);
  EXPECT_NE(err.find("global.th_min"), std::string::npos) << err;
  std::ofstream(dir / "bad3.yaml") << "local:\n  th_min: 0.99\n";
  EXPECT_EQ(run("config --config " + (dir / "bad3.yaml"), &err), 2);
  EXPECT_NE(err.find("local.th_min"), std::string::npos) << err;

  // Unwritable output: a path below a regular file.
  std::filesystem::create_directories(dir / "seq");
  std::ofstream(dir / "seq/000000.bin") << std::string(16 * 200, '\0');
  std::ofstream(dir / "file") << "x";
  EXPECT_EQ(run("map " + (dir / "seq") + " -o " + (dir / "file/out"), &err), 2);
  EXPECT_NE(err.find("file/out"), std::string::npos) << err;
  EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << err;
}

TEST(Mapping, ConfigRoundTripsThroughYaml) {
  test::TempDir dir;
  MappingConfig c;
  c.local.th_max = 0.9;
  c.global.mode = GlobalMode::sliding_window;
  c.output.pcd = true;
  std::ofstream(dir / "c.yaml") << c.to_yaml();
  const MappingConfig back = MappingConfig::load(dir / "c.yaml");
  EXPECT_EQ(back.local.th_max, 0.9);
  EXPECT_EQ(back.global.mode, GlobalMode::sliding_window);
  EXPECT_TRUE(back.output.pcd);
  EXPECT_EQ(back.to_yaml(), c.to_yaml());
  // A string survives whatever it holds: YAML syntax, quotes, a line break, a tab, a control byte
  // (in single quotes a trailing line break came back as a space; found by fuzz_config).
  c.preprocess.elevation_calibration = "a: 'b' \"c\" #d \\e\nf\tg\x01h\n";
  const MappingConfig strange = MappingConfig::parse(c.to_yaml(), "strange.yaml");
  EXPECT_EQ(strange.preprocess.elevation_calibration, c.preprocess.elevation_calibration);
  EXPECT_EQ(strange.to_yaml(), c.to_yaml());
  // Paper defaults.
  const MappingConfig d;
  EXPECT_EQ(d.local.th_max, 0.95);
  EXPECT_EQ(d.local.th_min, 0.10);
  EXPECT_EQ(d.local.max_keyframes, 15);
  EXPECT_EQ(d.global.th_min, 0.025);
  // Impossible source subsamples are refused, naming the key.
  MappingConfig bad;
  bad.global.factor_source_points = 10;
  EXPECT_THROW(bad.validate(), Error);
  bad = MappingConfig{};
  bad.local.factor_source_points = -1;
  try {
    bad.validate();
    ADD_FAILURE() << "local.factor_source_points -1 accepted";
  } catch (const Error& e) { EXPECT_NE(std::string(e.what()).find("local.factor_source_points"), std::string::npos) << e.what(); }
}

TEST(Mapping, Kitti00OdometryAgreesWithScanToScanGicp) {
  GCMAP_REQUIRE_SHARED_DATA("kitti00_first16");
  const std::string seq = test::shared_data() + "/kitti00_first16";
  test::TempDir dir;
  // Both sides see the scans as stored (no 0.22 degree correction), preprocessed the same way.
  {
    std::ofstream cfg(dir / "cfg.yaml");
    cfg << "preprocess:\n  kitti_vertical_correction: false\n";
  }
  std::string err;
  ASSERT_EQ(run("map " + seq + " -o " + (dir / "out") + " --quiet --config " + (dir / "cfg.yaml"), &err), 0) << err;
  const Poses odom = read_trajectory(dir / "out/odometry.kitti").poses;
  ASSERT_EQ(odom.size(), 16u);
  EXPECT_EQ(read_trajectory(dir / "out/trajectory.kitti").size(), 16u);

  // Independent front end: kNN GICP from each scan to the previous one, constant-velocity start.
  std::vector<PointCloud> scans;
  for (int k = 0; k < 16; ++k) {
    char name[32];
    std::snprintf(name, sizeof(name), "/velodyne/%06d.bin", k);
    scans.push_back(preprocess_scan(read_point_cloud(seq + name), PreprocessConfig{}));
  }
  Eigen::Isometry3d guess = Eigen::Isometry3d::Identity();
  double worst = 0.0;
  for (int k = 1; k < 16; ++k) {
    const GicpTarget target(std::make_shared<const PointCloud>(scans[k - 1]));
    const RegistrationResult r = align_gicp(scans[k], target, guess);
    ASSERT_TRUE(r.converged) << "frame " << k;
    guess = r.T_target_source;
    const double diff = test::translation_error(odom[k - 1].inverse() * odom[k], r.T_target_source);
    worst = std::max(worst, diff);
    EXPECT_LT(diff, 0.02) << "frame " << k;
    EXPECT_LT(test::rotation_error_deg(odom[k - 1].inverse() * odom[k], r.T_target_source), 0.1) << "frame " << k;
  }
  std::printf("largest per-frame difference odometry vs GICP: %.4f m\n", worst);
  // The data README quotes 0.69 m for the first motion from two GICP implementations.
  EXPECT_NEAR((odom[0].inverse() * odom[1]).translation().norm(), 0.69, 0.02);
}

TEST(Mapping, Kitti00SessionReloadsAndLocalizesItsOwnScans) {
  // Smoke test of sessions on real scans: the session of a run reads back, `session info` reads it,
  // and the run's own scans localize on it from no initial pose, where the run placed them.
  GCMAP_REQUIRE_SHARED_DATA("kitti00_first16");
  const std::string seq = test::shared_data() + "/kitti00_first16";
  test::TempDir dir;
  std::string err;
  ASSERT_EQ(run("map " + seq + " -o " + (dir / "out") + " --quiet", &err), 0) << err;
  ASSERT_EQ(run("session info " + (dir / "out"), &err), 0) << err;
  const Session session = read_session(dir / "out/session");
  const Poses mapped = read_trajectory(dir / "out/trajectory.kitti").poses;
  ASSERT_EQ(session.trajectory.size(), 16u);
  for (size_t f = 0; f < mapped.size(); ++f) EXPECT_LT(test::translation_error(session.trajectory[f], mapped[f]), 1e-6);
  EXPECT_GE(session.submaps.size(), 1u);

  ASSERT_EQ(
      run("localize --map " + (dir / "out") + " " + seq + " -o " + (dir / "loc") + " --global-init --start 4 --quiet", &err), 0)
      << err;
  const Poses localized = read_trajectory(dir / "loc/trajectory.kitti").poses;
  ASSERT_EQ(localized.size(), 12u);
  const std::string report = read_file(dir / "loc/localization.json");
  EXPECT_EQ(report.find("\"lost\""), std::string::npos) << report.substr(0, 400);
  for (size_t k = 0; k < localized.size(); ++k) {
    EXPECT_LT(test::translation_error(localized[k], mapped[k + 4]), 0.05) << "frame " << k + 4;
    EXPECT_LT(test::rotation_error_deg(localized[k], mapped[k + 4]), 0.2) << "frame " << k + 4;
  }
}

}  // namespace
}  // namespace gcmap
