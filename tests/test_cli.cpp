// End-to-end checks of the gcmap binary: exit codes, one-line errors, JSON output.
#include <array>
#include <cstdio>
#include <fstream>
#include <regex>

#include "gcmap/core/preprocess.hpp"
#include "gcmap/io/point_cloud_io.hpp"
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
  for (const char* key : {"\"T_target_source\":[[", "\"converged\":true", "\"num_inliers\":", "\"overlap\":",
                          "\"time_ms\":{\"preprocess\":", "\"align\":"})
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
