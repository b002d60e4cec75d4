// Trajectories that are no trajectory are refused naming the file and line; eval never reports a
// figure it could not compute; mme shows progress.
#include <fstream>

#include "gcmap/core/error.hpp"
#include "gcmap/io/point_cloud_io.hpp"
#include "gcmap/io/trajectory_io.hpp"
#include "gcmap/sim/synthetic.hpp"
#include "test_util.hpp"

namespace gcmap {
namespace {

void write_text(const std::string& path, const std::string& text) { std::ofstream(path) << text; }

std::string read_error(const std::string& path) {
  try {
    read_trajectory(path);
  } catch (const Error& e) { return e.what(); }
  return "(no error)";
}

// n poses, `step` m apart along x, in KITTI format.
std::string kitti_line(double x) { return "1 0 0 " + std::to_string(x) + " 0 1 0 0 0 0 1 0\n"; }
std::string straight_kitti(int n, double step) {
  std::string s;
  for (int i = 0; i < n; ++i) s += kitti_line(i * step);
  return s;
}

TEST(TrajectoryChecks, AbsurdTranslationsAreRefusedNamingFileAndLine) {
  test::TempDir dir;
  write_text(dir / "k.txt", kitti_line(0) + "1 0 0 1e308 0 1 0 0 0 0 1 0\n");
  write_text(dir / "t.txt", "0 0 0 0 0 0 0 1\n0.1 0 -2e7 0 0 0 0 1\n");
  write_text(dir / "g.txt", "v0 0 0 0 0 0 0 1\nv1 0 0 0 0 0 0 1\nv2 0 0 1e8 0 0 0 1\n");
  write_text(dir / "inf.txt", kitti_line(0) + "1 0 0 inf 0 1 0 0 0 0 1 0\n");
  EXPECT_NE(read_error(dir / "k.txt").find("k.txt:2: translation beyond 1e7 m"), std::string::npos) << read_error(dir / "k.txt");
  EXPECT_NE(read_error(dir / "t.txt").find("t.txt:2: translation beyond 1e7 m"), std::string::npos) << read_error(dir / "t.txt");
  EXPECT_NE(read_error(dir / "g.txt").find("g.txt:3: translation beyond 1e7 m"), std::string::npos) << read_error(dir / "g.txt");
  EXPECT_NE(read_error(dir / "inf.txt").find("inf.txt:2:"), std::string::npos) << read_error(dir / "inf.txt");
  // Within the bound (a UTM northing is under 1e7 m) is a pose.
  write_text(dir / "utm.txt", kitti_line(0) + kitti_line(9.9e6));
  EXPECT_EQ(read_trajectory(dir / "utm.txt").size(), 2u);
}

TEST(TrajectoryChecks, EvalRefusesHostileTrajectoriesNamingTheFile) {
  test::TempDir dir;
  write_text(dir / "gt.txt", straight_kitti(20, 1.0));
  write_text(dir / "huge.txt", straight_kitti(19, 1.0) + kitti_line(-1e308));
  const test::CliRun huge = test::run_gcmap("eval --gt " + (dir / "gt.txt") + " --est " + (dir / "huge.txt"));
  EXPECT_EQ(huge.code, 2);
  EXPECT_NE(huge.err.find("huge.txt:20: translation beyond"), std::string::npos) << huge.err;
  EXPECT_EQ(huge.out, "");
  write_text(dir / "one.txt", kitti_line(0));
  const test::CliRun one = test::run_gcmap("eval --gt " + (dir / "one.txt") + " --est " + (dir / "one.txt"));
  EXPECT_EQ(one.code, 2);
  EXPECT_NE(one.err.find("one.txt: has 1 pose, eval needs at least 2"), std::string::npos) << one.err;
}

TEST(TrajectoryChecks, EvalWithoutA100mSegmentSaysSoInsteadOfZero) {
  test::TempDir dir;
  write_text(dir / "short.txt", straight_kitti(60, 1.0));  // 59 m
  const test::CliRun s = test::run_gcmap("eval --gt " + (dir / "short.txt") + " --est " + (dir / "short.txt"));
  ASSERT_EQ(s.code, 0) << s.err;
  EXPECT_NE(s.out.find("\"translation_percent\":null"), std::string::npos) << s.out;
  EXPECT_NE(s.out.find("\"rotation_deg_per_100m\":null"), std::string::npos) << s.out;
  EXPECT_NE(s.out.find("\"note\":\"no segment of 100 m or more"), std::string::npos) << s.out;
  EXPECT_EQ(s.out.find("\"translation_percent\":0"), std::string::npos) << s.out;
  EXPECT_NE(s.err.find("short.txt: no segment of 100 m or more"), std::string::npos) << s.err;
  // 150 m: the 100 m figures are numbers, the longer lengths without segments are null.
  write_text(dir / "long.txt", straight_kitti(151, 1.0));
  const test::CliRun l = test::run_gcmap("eval --gt " + (dir / "long.txt") + " --est " + (dir / "long.txt"));
  ASSERT_EQ(l.code, 0) << l.err;
  EXPECT_NE(l.out.find("\"translation_percent\":0,"), std::string::npos) << l.out;
  EXPECT_EQ(l.out.find("\"note\""), std::string::npos) << l.out;
  EXPECT_NE(l.out.find("\"length_m\":200,\"count\":0,\"translation_percent\":null"), std::string::npos) << l.out;
  EXPECT_EQ(l.err, "");
}

TEST(TrajectoryChecks, MmeShowsProgressAndQuietSilencesIt) {
  test::TempDir dir;
  write_ply(dir / "m.ply", make_structured_scene(20000, 1));
  const test::CliRun r = test::run_gcmap("mme " + (dir / "m.ply"));
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.err.find("mme: point 20000/20000"), std::string::npos) << r.err;
  const test::CliRun q = test::run_gcmap("mme " + (dir / "m.ply") + " --quiet");
  ASSERT_EQ(q.code, 0) << q.err;
  EXPECT_EQ(q.err, "");
  EXPECT_EQ(q.out.substr(0, 6), r.out.substr(0, 6));  // {"mme": the same figure
}

}  // namespace
}  // namespace gcmap
