// The session format on small hand-made sessions: intensities (version 2), version 1 still read,
// damaged intensity blocks refused with the file named.
#include <cstring>
#include <filesystem>
#include <fstream>

#include "gcmap/core/error.hpp"
#include "gcmap/io/file.hpp"
#include "gcmap/mapping/mapper.hpp"
#include "gcmap/session/session.hpp"
#include "test_util.hpp"

namespace gcmap {
namespace {

Eigen::Isometry3d at(double x, double y, double z) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Eigen::Vector3d(x, y, z);
  return T;
}

// Two submaps of four points (submap 1 10 m east), one keyframe each; intensities per submap when asked.
Session small_session(bool intensities0, bool intensities1) {
  Session s;
  s.created_by = "test";
  for (int k = 0; k < 2; ++k) {
    Submap m;
    m.id = k;
    m.keyframes = {k};
    m.T_submap_keyframe = {at(0.5 * k, 0, 0)};
    auto cloud = std::make_shared<PointCloud>();
    for (int i = 0; i < 4; ++i) {
      cloud->points.emplace_back(1.0f * i, 2.0f + k, 0.25f * i);
      cloud->covs.push_back(Eigen::Matrix3f::Identity() * (0.01f + 0.01f * i));
    }
    // Raw values (not only [0, 1]) and exact in float: they must come back bit for bit.
    if (k == 0 ? intensities0 : intensities1) cloud->intensities = {0.0f, 0.125f + k, 37.5f, 255.0f};
    m.cloud = cloud;
    s.submaps.push_back(m);
  }
  s.T_world_submap = {at(0, 0, 0), at(10, 0, 0)};
  s.trajectory = {at(0, 0, 0), at(10, 0, 0)};
  s.stamps = {1.0, 1.1};
  return s;
}

std::string error_of(const std::string& dir) {
  try {
    read_session(dir);
  } catch (const Error& e) { return e.what(); }
  return "";
}

void overwrite(const std::string& path, const std::string& bytes) {
  std::ofstream(path, std::ios::binary | std::ios::trunc).write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

TEST(SessionFormat, IntensitiesComeBackPerSubmap) {
  test::TempDir dir;
  const Session written = small_session(true, false);
  write_session(dir / "s", written);
  const Session s = read_session(dir / "s");
  EXPECT_EQ(s.version, 2);
  ASSERT_EQ(s.submaps.size(), 2u);
  EXPECT_EQ(s.submaps[0].cloud->intensities, written.submaps[0].cloud->intensities);
  EXPECT_FALSE(s.submaps[1].cloud->has_intensities());
  EXPECT_FALSE(session_info(s, dir / "s").intensities);  // not every submap has them

  write_session(dir / "both", small_session(true, true));
  const Session both = read_session(dir / "both");
  EXPECT_EQ(both.submaps[1].cloud->intensities, (std::vector<float>{0.0f, 1.125f, 37.5f, 255.0f}));
  const SessionInfo info = session_info(both, dir / "both");
  EXPECT_TRUE(info.intensities);
  // 4 bytes a point more than the same session without (both carry a flag a submap).
  write_session(dir / "none", small_session(false, false));
  EXPECT_EQ(info.bytes - session_info(read_session(dir / "none"), dir / "none").bytes, 8u * 4u);
}

TEST(SessionFormat, AssembledMapKeepsIntensityOnlyWhenEverySubmapHasIt) {
  const Session both = small_session(true, true), one = small_session(true, false);
  const PointCloud map = assemble_map(both.submaps, both.T_world_submap, 0.01);
  ASSERT_EQ(map.size(), 8u);  // no two points share a voxel
  ASSERT_EQ(map.intensities.size(), 8u);
  float sum = 0.f;
  for (float v : map.intensities) sum += v;
  EXPECT_FLOAT_EQ(sum, 2.f * (0.125f + 37.5f + 255.f) + 1.f);
  EXPECT_FALSE(assemble_map(one.submaps, one.T_world_submap, 0.01).has_intensities());
  EXPECT_THROW(assemble_map(both.submaps, {at(0, 0, 0)}, 0.01), Error);
}

// A version 1 submaps.bin as that format laid it out, written byte by byte here.
std::string version1_bin(const Session& s) {
  std::string b("GCMAPSM1", 8);
  const auto u32 = [&](uint32_t v) { b.append(reinterpret_cast<const char*>(&v), 4); };
  const auto pose = [&](const Eigen::Isometry3d& T) {
    const Eigen::Quaterniond q(T.linear());
    const double v[7] = {T.translation().x(), T.translation().y(), T.translation().z(), q.x(), q.y(), q.z(), q.w()};
    b.append(reinterpret_cast<const char*>(v), sizeof v);
  };
  u32(1);
  u32(static_cast<uint32_t>(s.submaps.size()));
  for (size_t k = 0; k < s.submaps.size(); ++k) {
    const Submap& m = s.submaps[k];
    u32(static_cast<uint32_t>(m.id));
    pose(s.T_world_submap[k]);
    pose(m.T_odom);
    u32(1);
    u32(static_cast<uint32_t>(m.keyframes[0]));
    pose(m.T_submap_keyframe[0]);
    u32(0), u32(0);  // no descriptors
    u32(static_cast<uint32_t>(m.cloud->size()));
    for (const Eigen::Vector3f& p : m.cloud->points) b.append(reinterpret_cast<const char*>(p.data()), 12);
    for (const Eigen::Matrix3f& c : m.cloud->covs) {
      const float v[6] = {c(0, 0), c(0, 1), c(0, 2), c(1, 1), c(1, 2), c(2, 2)};
      b.append(reinterpret_cast<const char*>(v), sizeof v);
    }
  }
  return b;
}

TEST(SessionFormat, Version1SessionsAreStillReadWithoutIntensity) {
  test::TempDir dir;
  const Session written = small_session(false, false);
  write_session(dir / "v1", written);  // manifest, config and trajectory as version 1 had them
  overwrite(dir / "v1/submaps.bin", version1_bin(written));
  std::string manifest = read_file(dir / "v1/manifest.yaml");
  manifest.replace(manifest.find("version: 2"), 10, "version: 1");
  overwrite(dir / "v1/manifest.yaml", manifest);
  const Session s = read_session(dir / "v1");
  EXPECT_EQ(s.version, 1);
  ASSERT_EQ(s.submaps.size(), 2u);
  for (size_t k = 0; k < 2; ++k) {
    EXPECT_EQ(s.submaps[k].cloud->points, written.submaps[k].cloud->points);
    EXPECT_EQ(s.submaps[k].cloud->covs, written.submaps[k].cloud->covs);
    EXPECT_FALSE(s.submaps[k].cloud->has_intensities());
    EXPECT_LT(test::translation_error(s.T_world_submap[k], written.T_world_submap[k]), 1e-12);
  }
  // The version 2 layout under a version 1 header is refused, not misread.
  write_session(dir / "mixed", written);
  std::string bin = read_file(dir / "mixed/submaps.bin");
  bin[8] = 1;
  overwrite(dir / "mixed/submaps.bin", bin);
  overwrite(dir / "mixed/manifest.yaml", manifest);
  EXPECT_NE(error_of(dir / "mixed").find("submaps.bin: "), std::string::npos);
}

TEST(SessionFormat, DamagedIntensityBlocksAreRefusedNamingTheFile) {
  test::TempDir dir;
  write_session(dir / "s", small_session(true, true));
  const std::string bin = read_file(dir / "s/submaps.bin");
  const std::string path = dir / "s/submaps.bin";
  // The last submap ends in its flag and 4 intensities: cut inside them, after the flag, before it.
  for (size_t cut : {size_t{1}, size_t{8}, size_t{16}, size_t{17}}) {
    overwrite(path, bin.substr(0, bin.size() - cut));
    const std::string e = error_of(dir / "s");
    EXPECT_EQ(e.rfind(path + ": ", 0), 0u) << e;
    if (cut <= 16) EXPECT_NE(e.find("4 intensities do not fit in the " + std::to_string(16 - cut)), std::string::npos) << e;
  }
  std::string flag = bin;
  flag[bin.size() - 17] = 2;
  overwrite(path, flag);
  EXPECT_NE(error_of(dir / "s").find(path + ": submap 1: intensity flag 2 is neither 0 nor 1"), std::string::npos);
  overwrite(path, bin + "x");
  EXPECT_NE(error_of(dir / "s").find("unexpected bytes after the last submap"), std::string::npos);
  overwrite(path, bin);
  EXPECT_EQ(error_of(dir / "s"), "");  // the checks above damaged only what they changed
}

TEST(SessionFormat, WriterRefusesACloudWhoseIntensitiesDoNotMatchItsPoints) {
  test::TempDir dir;
  Session s = small_session(true, true);
  auto cloud = std::make_shared<PointCloud>(*s.submaps[1].cloud);
  cloud->intensities.pop_back();
  s.submaps[1].cloud = cloud;
  try {
    write_session(dir / "s", s);
    ADD_FAILURE() << "3 intensities for 4 points must be refused";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()), (dir / "s") + ": submap 1 has 4 points, 4 covariances and 3 intensities");
  }
  EXPECT_FALSE(std::filesystem::exists(dir / "s"));
}

}  // namespace
}  // namespace gcmap
