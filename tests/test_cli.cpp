// End-to-end checks of the gcmap binary: exit codes, one-line errors, JSON output.
#include <array>
#include <cstdio>
#include <fstream>
#include <regex>
#include <sstream>

#include "gcmap/core/preprocess.hpp"
#include "gcmap/io/file.hpp"
#include "gcmap/io/imu_io.hpp"
#include "gcmap/io/point_cloud_io.hpp"
#include "gcmap/mapping/config.hpp"
#include "gcmap/sim/synthetic.hpp"
#include "test_util.hpp"

namespace gcmap {
namespace {

struct RunResult {
  int code;
  std::string out;  // stdout
  std::string err;  // stderr
};

RunResult run_cli(const std::string& args) {
  test::TempDir tmp;
  const std::string cmd = std::string(GCMAP_CLI) + " " + args + " >" + (tmp / "out") + " 2>" + (tmp / "err");
  const int status = std::system(cmd.c_str());
  auto slurp = [](const std::string& p) {
    std::ifstream in(p);
    return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  };
  return {WEXITSTATUS(status), slurp(tmp / "out"), slurp(tmp / "err")};
}

TEST(Cli, RegisterPrintsJsonAndRecoversTransform) {
  test::TempDir dir;
  PointCloud target = make_structured_scene(30000, 1);
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() << 0.4, -0.2, 0.05;
  write_ply(dir / "t.ply", target);
  write_pcd(dir / "s.pcd", transformed(make_structured_scene(30000, 2), T.inverse()));
  const RunResult r = run_cli("register " + (dir / "t.ply") + " " + (dir / "s.pcd") + " --voxel 0.5 --downsample 0.2");
  ASSERT_EQ(r.code, 0) << r.err;
  for (const char* key : {"\"T_target_source\":[[", "\"converged\":true",
                          "\"num_inliers\":", "\"overlap\":", "\"time_ms\":{\"preprocess\":", "\"align\":"})
    EXPECT_NE(r.out.find(key), std::string::npos) << key << " in " << r.out;
  // Row 0, column 3 is x.
  const size_t pos = r.out.find("[[");
  double m[4];
  ASSERT_EQ(std::sscanf(r.out.c_str() + pos, "[[%lf,%lf,%lf,%lf", &m[0], &m[1], &m[2], &m[3]), 4);
  EXPECT_NEAR(m[3], 0.4, 0.05);
}

TEST(Cli, SimulateRejectsConflictingRealism) {
  test::TempDir dir;
  const RunResult a = run_cli("simulate -o " + (dir / "s") + " --scenario city --frames 2 --ideal --realism all");
  EXPECT_EQ(a.code, 2);
  EXPECT_NE(a.err.find("--ideal and --realism"), std::string::npos) << a.err;
  const RunResult b = run_cli("simulate -o " + (dir / "s") + " --scenario city --frames 2 --realism labels,wobble");
  EXPECT_EQ(b.code, 2);
  EXPECT_NE(b.err.find("--realism: unknown key 'wobble'"), std::string::npos) << b.err;
  EXPECT_EQ(std::count(b.err.begin(), b.err.end(), '\n'), 1) << b.err;
}

TEST(Cli, SimulateTakesTheImuNoiseAsked) {
  test::TempDir dir;
  const std::string drive = "simulate --scenario city --frames 10 --imu -o ";
  const RunResult exact = run_cli(drive + (dir / "exact") + " --imu-noise-free");
  ASSERT_EQ(exact.code, 0) << exact.err;
  const RunResult noisy = run_cli(drive + (dir / "noisy") + " --imu-gyro-noise 2.4e-4 --imu-accel-noise 5e-3");
  ASSERT_EQ(noisy.code, 0) << noisy.err;
  EXPECT_NE(test::slurp(dir / "noisy/scenario.json").find("\"gyro_noise_density\":0.00024"), std::string::npos);
  // Less the exact samples and the true biases, what stays is the white noise: density / sqrt(dt).
  const ImuStream a = read_imu_txt(dir / "exact/imu.txt"), b = read_imu_txt(dir / "noisy/imu.txt");
  std::vector<ImuSample> bias;  // stamp, gyro, accel per line; no gravity in it to read the unit by
  std::ifstream in(dir / "noisy/imu_bias.txt");
  for (std::string line; std::getline(in, line);) {
    ImuSample x;
    if (line[0] != '#' && std::istringstream(line) >> x.stamp >> x.gyro.x() >> x.gyro.y() >> x.gyro.z() >> x.accel.x() >>
                              x.accel.y() >> x.accel.z())
      bias.push_back(x);
  }
  ASSERT_EQ(a.samples.size(), b.samples.size());
  ASSERT_EQ(bias.size(), b.samples.size());
  double gyro = 0.0, accel = 0.0;
  for (size_t k = 0; k < b.samples.size(); ++k) {
    gyro += (b.samples[k].gyro - a.samples[k].gyro - bias[k].gyro).squaredNorm();
    accel += (b.samples[k].accel - a.samples[k].accel - bias[k].accel).squaredNorm();
  }
  const double n = 3.0 * static_cast<double>(b.samples.size());
  EXPECT_NEAR(std::sqrt(gyro / n), 2.4e-4 * std::sqrt(200.0), 0.1 * 2.4e-4 * std::sqrt(200.0));
  EXPECT_NEAR(std::sqrt(accel / n), 5e-3 * std::sqrt(200.0), 0.1 * 5e-3 * std::sqrt(200.0));

  for (const auto& [args, message] : std::vector<std::pair<std::string, std::string>>{
           {"--imu-gyro-noise 1e-4", "--imu-gyro-noise needs --imu"},
           {"--imu --imu-noise-free --imu-accel-noise 0.01", "--imu-noise-free has no noise"},
           {"--imu --imu-gyro-noise -1", "--imu-gyro-noise: expected 0 to 0.1"}}) {
    const RunResult r = run_cli("simulate --scenario small --frames 2 -o " + (dir / "bad") + " " + args);
    EXPECT_EQ(r.code, 2) << args;
    EXPECT_NE(r.err.find(message), std::string::npos) << r.err;
  }
}

TEST(Cli, BadInputExitsTwoWithOneLine) {
  test::TempDir dir;
  std::ofstream(dir / "trunc.bin") << "0123456789";
  const RunResult a = run_cli("register " + (dir / "missing.bin") + " " + (dir / "trunc.bin"));
  EXPECT_EQ(a.code, 2);
  EXPECT_NE(a.err.find("missing.bin: no such file"), std::string::npos) << a.err;
  EXPECT_EQ(std::count(a.err.begin(), a.err.end(), '\n'), 1) << a.err;
  const RunResult b = run_cli("register " + (dir / "trunc.bin") + " " + (dir / "trunc.bin"));
  EXPECT_EQ(b.code, 2);
  EXPECT_NE(b.err.find("trunc.bin: size 10"), std::string::npos) << b.err;
  const RunResult c = run_cli("register a.bin b.bin --voxel -1");
  EXPECT_EQ(c.code, 2);
  EXPECT_NE(c.err.find("--voxel"), std::string::npos) << c.err;
  const RunResult d = run_cli("register a.bin b.bin --init \"1 2 3\"");
  EXPECT_EQ(d.code, 2);
  EXPECT_NE(d.err.find("--init"), std::string::npos) << d.err;
  const RunResult e = run_cli("no-such-command");
  EXPECT_EQ(e.code, 2);
}

TEST(Cli, ConfigRejectsValuesOutOfRangeNamingKeyAndFile) {
  test::TempDir dir;
  const std::vector<std::pair<std::string, std::string>> hostile = {
      {"preprocess:\n  downsample: 1e-300\n", "preprocess.downsample must be in [0.01, 100] m, got 1e-300"},
      {"loop:\n  rings: 2000000000\n", "loop.rings must be in [1, 200], got 2000000000"},
      {"loop:\n  sectors: 2000000000\n", "loop.sectors must be in [2, 360], got 2000000000"},
      {"preprocess:\n  num_neighbors: 2000000000\n", "preprocess.num_neighbors must be in [4, 100], got 2000000000"},
  };
  for (const auto& [yaml, message] : hostile) {
    std::ofstream(dir / "hostile.yaml") << yaml;
    const RunResult r = run_cli("config --config " + (dir / "hostile.yaml"));
    EXPECT_EQ(r.code, 2) << yaml;
    EXPECT_EQ(r.err, "gcmap: " + (dir / "hostile.yaml") + ": " + message + "\n");
    EXPECT_EQ(r.out, "");
  }
  // The defaults, dumped, load and dump the same.
  const RunResult defaults = run_cli("config");
  ASSERT_EQ(defaults.code, 0) << defaults.err;
  std::ofstream(dir / "defaults.yaml") << defaults.out;
  const RunResult back = run_cli("config --config " + (dir / "defaults.yaml"));
  EXPECT_EQ(back.code, 0) << back.err;
  EXPECT_EQ(back.out, defaults.out);
}

TEST(Cli, ConfigDescribePrintsEveryKey) {
  const RunResult text = run_cli("config --describe");
  ASSERT_EQ(text.code, 0) << text.err;
  EXPECT_EQ(text.out, config_reference_text());
  EXPECT_NE(text.out.find("loop.tukey_width"), std::string::npos);
  const RunResult markdown = run_cli("config --describe --markdown");
  ASSERT_EQ(markdown.code, 0) << markdown.err;
  EXPECT_EQ(markdown.out, read_file(std::string(GCMAP_SOURCE_DIR) + "/docs/config.md"));
  EXPECT_EQ(run_cli("config --markdown").code, 2);  // only with --describe
}

TEST(Cli, HelpDocumentsDefaults) {
  const RunResult r = run_cli("register --help");
  EXPECT_EQ(r.code, 0);
  EXPECT_NE(r.out.find("--downsample"), std::string::npos);
  EXPECT_NE(r.out.find("0.25"), std::string::npos);
}

TEST(Cli, VersionOnEveryCommand) {
  const RunResult top = run_cli("--version");
  EXPECT_EQ(top.code, 0) << top.err;
  EXPECT_TRUE(std::regex_match(top.out, std::regex("gcmap [0-9]+\\.[0-9]+\\.[0-9]+\n"))) << top.out;
  for (const char* command : {"register", "optimize", "simulate", "eval", "mme", "map", "demo", "config"}) {
    const RunResult r = run_cli(std::string(command) + " --version");
    EXPECT_EQ(r.code, 0) << command << ": " << r.err;
    EXPECT_EQ(r.out, top.out) << command;
  }
}

}  // namespace
}  // namespace gcmap
