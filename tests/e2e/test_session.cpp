// Sessions: a mapping run written to disk and read back.
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <thread>

#include "gcmap/core/error.hpp"
#include "gcmap/io/file.hpp"
#include "gcmap/session/session.hpp"
#include "gcmap/sim/simulator.hpp"
#include "test_util.hpp"

namespace gcmap {
namespace {

class SessionRoundTrip : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    sim::SimulationConfig sc;
    sc.scenario = "small";
    const sim::Simulator sim(sc);
    pipeline = new MappingPipeline(MappingConfig{});
    for (size_t f = 0; f < 45; ++f) pipeline->add_scan(sim.scan(f), 0.1 * f);
    pipeline->finish();
    dir = new test::TempDir();
    std::vector<double> stamps;
    for (size_t f = 0; f < 45; ++f) stamps.push_back(0.1 * f);
    write_session(*dir / "session", *pipeline, stamps);
  }
  static void TearDownTestSuite() {
    delete pipeline;
    delete dir;
  }
  // A copy of the session folder to damage.
  static std::string copy(const std::string& name) {
    const std::string to = *dir / name;
    std::filesystem::copy(*dir / "session", to, std::filesystem::copy_options::recursive);
    return to;
  }
  static MappingPipeline* pipeline;
  static test::TempDir* dir;
};
MappingPipeline* SessionRoundTrip::pipeline = nullptr;
test::TempDir* SessionRoundTrip::dir = nullptr;

TEST_F(SessionRoundTrip, ReadsBackWhatWasWritten) {
  const Session s = read_session(*dir / "session");
  EXPECT_EQ(s.version, kSessionVersion);
  ASSERT_EQ(s.submaps.size(), pipeline->submaps().size());
  ASSERT_GE(s.submaps.size(), 2u);
  ASSERT_EQ(s.trajectory.size(), 45u);
  const std::vector<Eigen::Isometry3d> traj = pipeline->trajectory();
  for (size_t f = 0; f < traj.size(); ++f) EXPECT_LT(test::translation_error(s.trajectory[f], traj[f]), 1e-6);
  EXPECT_NEAR(s.stamps[44], 4.4, 1e-9);
  for (size_t k = 0; k < s.submaps.size(); ++k) {
    const Submap& a = pipeline->submaps()[k];
    const Submap& b = s.submaps[k];
    EXPECT_EQ(b.keyframes, a.keyframes);
    ASSERT_EQ(b.cloud->size(), a.cloud->size());
    // Points exactly; covariances as their upper triangle (float products leave them asymmetric
    // by rounding only).
    float point_diff = 0.f, cov_diff = 0.f;
    for (size_t i = 0; i < a.cloud->size(); ++i) {
      point_diff = std::max(point_diff, (b.cloud->points[i] - a.cloud->points[i]).cwiseAbs().maxCoeff());
      cov_diff = std::max(cov_diff, (b.cloud->covs[i] - a.cloud->covs[i]).cwiseAbs().maxCoeff());
    }
    EXPECT_EQ(point_diff, 0.f);
    EXPECT_LT(cov_diff, 1e-6f);
    ASSERT_TRUE(a.cloud->has_intensities());  // the simulator's scans have intensity
    EXPECT_EQ(b.cloud->intensities, a.cloud->intensities);
    EXPECT_FALSE(b.factor_source->has_intensities());  // as the run kept it: no memory for what factors skip
    ASSERT_EQ(b.descriptors.size(), a.descriptors.size());
    EXPECT_EQ(b.descriptors.back().cells, a.descriptors.back().cells);
    EXPECT_EQ(b.voxels->num_voxels(), a.voxels->num_voxels());  // rebuilt at the same resolution
    const Eigen::Isometry3d T = pipeline->mapper().output_from_world() * pipeline->mapper().submap_pose(a.id);
    EXPECT_LT(test::translation_error(s.T_world_submap[k], T), 1e-9);
  }
  ASSERT_EQ(s.factors.size(), pipeline->factors().size());
  for (size_t f = 0; f < s.factors.size(); ++f) {
    EXPECT_EQ(s.factors[f].kind, pipeline->factors()[f].kind);
    EXPECT_EQ(s.factors[f].source, pipeline->factors()[f].source);
    EXPECT_EQ(s.factors[f].target, pipeline->factors()[f].target);
  }
  const SessionInfo info = session_info(s, *dir / "session");
  EXPECT_EQ(info.frames, 45u);
  EXPECT_GT(info.bytes, info.points * 36);
  EXPECT_GT(info.extent.sizes().x(), 20.0);  // 45 frames of a 10.7 m/s drive and 100 m of range
}

TEST_F(SessionRoundTrip, DamagedOrNewerSessionsAreRefusedWithTheFileNamed) {
  const std::string newer = copy("newer");
  std::string manifest = read_file(newer + "/manifest.yaml");
  const std::string current = "version: " + std::to_string(kSessionVersion);
  manifest.replace(manifest.find(current), current.size(), "version: " + std::to_string(kSessionVersion + 1));
  std::ofstream(newer + "/manifest.yaml") << manifest;
  try {
    read_session(newer);
    ADD_FAILURE() << "a newer version must be refused";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("newer than this gcmap reads"), std::string::npos) << e.what();
  }
  const std::string cut = copy("cut");
  const std::string bin = read_file(cut + "/submaps.bin");
  for (size_t len : {size_t{0}, size_t{7}, size_t{20}, size_t{150}, bin.size() / 2, bin.size() - 1}) {
    std::ofstream(cut + "/submaps.bin", std::ios::binary | std::ios::trunc).write(bin.data(), len);
    try {
      read_session(cut);
      ADD_FAILURE() << "a truncated submaps.bin (" << len << " bytes) must be refused";
    } catch (const Error& e) { EXPECT_NE(std::string(e.what()).find("submaps.bin"), std::string::npos) << e.what(); }
  }
  // A point count that would need gigabytes is checked against the file before allocating.
  std::ofstream(cut + "/submaps.bin", std::ios::binary | std::ios::trunc).write(bin.data(), 12);
  std::ofstream(cut + "/submaps.bin", std::ios::binary | std::ios::app).write("\xff\xff\xff\x7f", 4);
  EXPECT_THROW(read_session(cut), Error);
  EXPECT_THROW(read_session(*dir / "missing"), Error);
}

TEST_F(SessionRoundTrip, AWriterKilledAtAnyMomentLeavesAWholeSession) {
  // A child rewrites the session (with every submap 1 m further in x) over and over until it is
  // killed; whenever that happens, and while it writes, what is there reads as the old or the new.
  const std::string target = *dir / "killed";
  const Session before = read_session(*dir / "session");
  write_session(target, before);
  Session after = before;
  for (Eigen::Isometry3d& T : after.T_world_submap) T.translation().x() += 1.0;
  auto is_new = [&] {  // reads the session, which must be whole
    const Session s = read_session(target);
    EXPECT_EQ(s.submaps.size(), before.submaps.size());
    EXPECT_EQ(s.trajectory.size(), before.trajectory.size());
    const double dx = s.T_world_submap.back().translation().x() - before.T_world_submap.back().translation().x();
    EXPECT_TRUE(std::abs(dx) < 1e-9 || std::abs(dx - 1.0) < 1e-9) << dx;
    return std::abs(dx - 1.0) < 1e-9;
  };
  // Kills after 0-50 ms, then one once the new session has been seen (read while the child writes).
  for (int delay_us : {0, 200, 700, 1500, 3000, 6000, 12000, 25000, 50000, -1}) {
    const pid_t child = fork();
    ASSERT_GE(child, 0);
    if (child == 0) {
      try {
        for (;;) write_session(target, after);
      } catch (...) {}
      _exit(3);
    }
    if (delay_us >= 0) std::this_thread::sleep_for(std::chrono::microseconds(delay_us));
    for (int polls = 0; delay_us < 0 && !is_new() && polls < 6000; ++polls)
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    ::kill(child, SIGKILL);
    int status = 0;
    ASSERT_EQ(waitpid(child, &status, 0), child);
    ASSERT_TRUE(WIFSIGNALED(status)) << "the writer stopped by itself: exit " << WEXITSTATUS(status);
    if (delay_us < 0) EXPECT_TRUE(is_new());
    else is_new();
  }
  int interrupted = 0;  // kills inside a write leave its temporary folder behind
  for (const auto& e : std::filesystem::directory_iterator(dir->path))
    interrupted += e.path().filename().string().rfind("killed.tmp.", 0) == 0;
  EXPECT_GT(interrupted, 0);
}

}  // namespace
}  // namespace gcmap
