#include <cstdlib>
#include <fstream>

#include "gcmap/core/error.hpp"
#include "gcmap/io/file.hpp"
#include "gcmap/io/labels.hpp"
#include "gcmap/io/point_cloud_io.hpp"
#include "gcmap/io/trajectory_io.hpp"
#include "test_util.hpp"

namespace gcmap {
namespace {

void write_bytes(const std::string& path, const std::string& bytes) { std::ofstream(path, std::ios::binary) << bytes; }

PointCloud sample_cloud() {
  PointCloud c;
  for (int i = 0; i < 100; ++i) {
    c.points.emplace_back(0.5f * i, -0.25f * i, 1e3f + i);
    c.intensities.push_back(0.01f * i);
  }
  return c;
}

void expect_same(const PointCloud& a, const PointCloud& b) {
  ASSERT_EQ(a.size(), b.size());
  ASSERT_EQ(a.has_intensities(), b.has_intensities());
  for (size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a.points[i], b.points[i]);
    if (a.has_intensities()) EXPECT_EQ(a.intensities[i], b.intensities[i]);
  }
}

// Expects read_point_cloud to throw an Error naming the file and containing `what`.
void expect_error(const std::string& path, const std::string& what, BinFields f = BinFields::xyzi) {
  try {
    read_point_cloud(path, f);
    ADD_FAILURE() << path << ": no error";
  } catch (const Error& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find(path), std::string::npos) << msg;
    EXPECT_NE(msg.find(what), std::string::npos) << msg;
    EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
  }
}

TEST(PointCloudIO, PlyAndPcdRoundTrip) {
  test::TempDir dir;
  const PointCloud c = sample_cloud();
  write_ply(dir / "a.ply", c);
  expect_same(c, read_point_cloud(dir / "a.ply"));
  write_pcd(dir / "a.pcd", c);
  expect_same(c, read_point_cloud(dir / "a.pcd"));
  PointCloud no_i = c;
  no_i.intensities.clear();
  write_point_cloud(dir / "b.pcd", no_i);
  expect_same(no_i, read_point_cloud(dir / "b.pcd"));
  // No temporary file is left behind.
  size_t files = 0;
  for (auto& e : std::filesystem::directory_iterator(dir.path)) files += e.is_regular_file();
  EXPECT_EQ(files, 3u);
}

TEST(PointCloudIO, KittiAndXyzBin) {
  test::TempDir dir;
  const float xyzi[8] = {1, 2, 3, 0.5f, 4, 5, 6, 0.25f};
  write_bytes(dir / "a.bin", std::string(reinterpret_cast<const char*>(xyzi), sizeof(xyzi)));
  const PointCloud a = read_point_cloud(dir / "a.bin");
  ASSERT_EQ(a.size(), 2u);
  EXPECT_EQ(a.points[1], Eigen::Vector3f(4, 5, 6));
  EXPECT_EQ(a.intensities[0], 0.5f);
  const float xyz[6] = {1, 2, 3, 4, 5, 6};
  write_bytes(dir / "b.bin", std::string(reinterpret_cast<const char*>(xyz), sizeof(xyz)));
  EXPECT_EQ(read_point_cloud(dir / "b.bin", BinFields::xyz).points[1], Eigen::Vector3f(4, 5, 6));
  expect_error(dir / "b.bin", "not a multiple of 16");
}

TEST(PointCloudIO, BinRoundTrip) {
  test::TempDir dir;
  const PointCloud c = sample_cloud();
  write_point_cloud(dir / "a.bin", c);
  expect_same(c, read_point_cloud(dir / "a.bin"));
  write_point_cloud(dir / "b.bin", c, BinFields::xyz);
  EXPECT_EQ(std::filesystem::file_size(dir / "b.bin"), c.size() * 12);
  PointCloud no_i = c;
  no_i.intensities.clear();
  expect_same(no_i, read_point_cloud(dir / "b.bin", BinFields::xyz));
  write_point_cloud(dir / "c.bin", no_i);  // KITTI records: intensity 0
  const PointCloud back = read_point_cloud(dir / "c.bin");
  ASSERT_EQ(back.intensities.size(), c.size());
  EXPECT_EQ(back.intensities.front(), 0.0f);
}

TEST(PointCloudIO, AsciiFormatsAnyFieldOrderAndNaNDropped) {
  test::TempDir dir;
  write_bytes(dir / "a.pcd",
              "# comment\nVERSION .7\nFIELDS intensity z y x\nSIZE 4 4 4 8\nTYPE F F F F\nCOUNT 1 1 1 1\nWIDTH 3\n"
              "HEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 3\nDATA ascii\n0.5 3 2 1\n0.1 nan 0 0\n0.7 6 5 4\n");
  const PointCloud a = read_point_cloud(dir / "a.pcd");
  ASSERT_EQ(a.size(), 2u);  // the NaN point is dropped
  EXPECT_EQ(a.points[0], Eigen::Vector3f(1, 2, 3));
  EXPECT_FLOAT_EQ(a.intensities[1], 0.7f);

  write_bytes(dir / "a.ply",
              "ply\nformat ascii 1.0\ncomment x\nelement vertex 2\nproperty double z\nproperty float x\n"
              "property uchar red\nproperty float y\nelement face 1\nproperty list uchar int vertex_indices\n"
              "end_header\n3 1 255 2\n6 4 0 5\n3 0 1 2\n");
  const PointCloud b = read_point_cloud(dir / "a.ply");
  ASSERT_EQ(b.size(), 2u);
  EXPECT_EQ(b.points[1], Eigen::Vector3f(4, 5, 6));
  EXPECT_FALSE(b.has_intensities());
}

TEST(PointCloudIO, BigEndianPly) {
  test::TempDir dir;
  std::string body;
  for (float v : {1.f, 2.f, 3.f, -4.f, 5.f, 6.5f}) {
    char b[4];
    std::memcpy(b, &v, 4);
    std::reverse(b, b + 4);
    body.append(b, 4);
  }
  write_bytes(dir / "be.ply",
              "ply\nformat binary_big_endian 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"
              "property float z\nend_header\n" +
                  body);
  const PointCloud c = read_point_cloud(dir / "be.ply");
  ASSERT_EQ(c.size(), 2u);
  EXPECT_EQ(c.points[1], Eigen::Vector3f(-4.f, 5.f, 6.5f));
}

// LZF stream of literal runs only (valid LZF; the decoder must also handle back references).
std::string lzf_literals(const std::string& raw) {
  std::string out;
  for (size_t i = 0; i < raw.size(); i += 32) {
    const size_t n = std::min<size_t>(32, raw.size() - i);
    out.push_back(static_cast<char>(n - 1));
    out.append(raw, i, n);
  }
  return out;
}

TEST(PointCloudIO, PcdBinaryCompressed) {
  test::TempDir dir;
  // Column-major payload: x x, y y, z z.
  const float cols[6] = {1, 4, 2, 5, 3, 6};
  const std::string raw(reinterpret_cast<const char*>(cols), sizeof(cols));
  const std::string packed = lzf_literals(raw);
  std::string sizes(8, '\0');
  const uint32_t cs = packed.size(), us = raw.size();
  std::memcpy(&sizes[0], &cs, 4);
  std::memcpy(&sizes[4], &us, 4);
  const std::string header =
      "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 2\nHEIGHT 1\nPOINTS 2\nDATA binary_compressed\n";
  write_bytes(dir / "c.pcd", header + sizes + packed);
  const PointCloud c = read_point_cloud(dir / "c.pcd");
  ASSERT_EQ(c.size(), 2u);
  EXPECT_EQ(c.points[1], Eigen::Vector3f(4, 5, 6));
  // Truncated compressed payload.
  write_bytes(dir / "t.pcd", header + sizes + packed.substr(0, packed.size() - 3));
  expect_error(dir / "t.pcd", "truncated");
}

TEST(PointCloudIO, LzfBackReferences) {
  // "abcabcabcX": literal "abc", back reference of length 6 at distance 3, literal "X".
  const std::string stream = std::string(
                                 "\x02"
                                 "abc",
                                 4) +
                             std::string("\x80\x02", 2) + std::string("\x00X", 2);
  EXPECT_EQ(lzf_decompress(stream, 10), "abcabcabcX");
  EXPECT_THROW(lzf_decompress(std::string("\x80\x10", 2), 4), Error);  // reference before the start
}

TEST(PointCloudIO, MalformedInputGivesOneLineErrors) {
  test::TempDir dir;
  expect_error(dir / "missing.pcd", "no such file");
  write_bytes(dir / "empty.bin", "");
  expect_error(dir / "empty.bin", "empty");
  write_bytes(dir / "trunc.bin", std::string(20, '\0'));
  expect_error(dir / "trunc.bin", "not a multiple of 16");
  write_bytes(dir / "bad.pcd", "hello world\n");
  expect_error(dir / "bad.pcd", "not a PCD file");
  write_bytes(dir / "noxyz.pcd", "FIELDS a b c\nSIZE 4 4 4\nTYPE F F F\nWIDTH 1\nPOINTS 1\nDATA ascii\n1 2 3\n");
  expect_error(dir / "noxyz.pcd", "no field 'x'");
  write_bytes(dir / "short.pcd", "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 5\nPOINTS 5\nDATA binary\n" + std::string(13, 'a'));
  expect_error(dir / "short.pcd", "truncated");
  write_bytes(dir / "hdr.pcd", "FIELDS x y z\nSIZE 4 4 4\n");
  expect_error(dir / "hdr.pcd", "truncated header");
  write_bytes(dir / "bad.ply",
              "ply\nformat binary_little_endian 1.0\nelement vertex 10\nproperty float x\nproperty float y\nproperty float "
              "z\nend_header\nabc");
  expect_error(dir / "bad.ply", "truncated");
  write_bytes(dir / "weird.xyz", "1 2 3\n");
  expect_error(dir / "weird.xyz", "unknown point cloud format");
  write_bytes(dir / "magic.ply", "plx\n");
  expect_error(dir / "magic.ply", "not a PLY file");
}

// Sizes a header declares are checked against the bytes that follow before anything is allocated.
TEST(PointCloudIO, HeaderSizesAreCheckedAgainstTheData) {
  test::TempDir dir;
  const std::string xyz = "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\n";
  write_bytes(dir / "many.pcd", xyz + "WIDTH 2000000000\nDATA ascii\n1 2 3\n");
  expect_error(dir / "many.pcd", "the header declares 2000000000 points");
  write_bytes(dir / "nowidth.pcd", xyz + "DATA ascii\n1 2 3\n");
  expect_error(dir / "nowidth.pcd", "neither WIDTH nor POINTS");
  write_bytes(dir / "wrap.pcd", xyz + "WIDTH 4611686018427387904\nHEIGHT 4\nDATA binary\n");
  expect_error(dir / "wrap.pcd", "WIDTH*HEIGHT is too large");
  write_bytes(dir / "count.pcd", "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 4294967297 1\nWIDTH 1\nDATA ascii\n1 2 3\n");
  expect_error(dir / "count.pcd", "unsupported TYPE/SIZE/COUNT");
  write_bytes(dir / "eof.pcd", xyz + "WIDTH 1\nDATA binary");  // no byte after the header
  expect_error(dir / "eof.pcd", "truncated (0 of 1 points)");
  std::string sizes(8, '\0');
  const uint32_t declared[2] = {4, 4294967292u};
  std::memcpy(&sizes[0], declared, 8);
  write_bytes(dir / "lzf.pcd", xyz + "WIDTH 357913941\nDATA binary_compressed\n" + sizes +
                                   "\x02"
                                   "abc");
  expect_error(dir / "lzf.pcd", "4 bytes cannot expand to 4294967292");
  const std::string ply =
      "ply\nformat binary_little_endian 1.0\nelement vertex 1537228672809129302\nproperty float x\n"
      "property float y\nproperty float z\nend_header\n";
  write_bytes(dir / "wrap.ply", ply + std::string(8, '\0'));
  expect_error(dir / "wrap.ply", "truncated (0 of 1537228672809129302 vertices)");
}

TEST(Labels, ReadsSemanticKittiLabelsAndChecksTheCount) {
  test::TempDir dir;
  const uint32_t labels[3] = {40, 252u | (7u << 16), 10};
  write_bytes(dir / "a.label", std::string(reinterpret_cast<const char*>(labels), sizeof(labels)));
  const std::vector<uint32_t> back = read_labels(dir / "a.label", 3);
  ASSERT_EQ(back.size(), 3u);
  EXPECT_EQ(semantic_class(back[1]), 252);
  EXPECT_TRUE(is_moving_class(back[1]));
  EXPECT_FALSE(is_moving_class(back[0]));
  auto expect_label_error = [&](const std::string& path, size_t n, const std::string& what) {
    try {
      read_labels(path, n);
      ADD_FAILURE() << path;
    } catch (const Error& e) { EXPECT_NE(std::string(e.what()).find(path + ": " + what), std::string::npos) << e.what(); }
  };
  expect_label_error(dir / "a.label", 4, "3 labels for 4 points");
  write_bytes(dir / "t.label", "1234567");
  expect_label_error(dir / "t.label", 2, "size 7 is not a multiple of 4");
  expect_label_error(dir / "missing.label", 1, "no such file");
}

TEST(TrajectoryIO, RoundTripsAndDetectsFormats) {
  test::TempDir dir;
  std::mt19937_64 rng(3);
  for (TrajectoryFormat f : {TrajectoryFormat::kitti, TrajectoryFormat::tum, TrajectoryFormat::named}) {
    Trajectory t;
    t.format = f;
    for (int i = 0; i < 5; ++i) {
      t.poses.push_back(test::random_pose(rng, 2.0, 50.0));
      t.stamps.push_back(0.1 * i);
      t.names.push_back("v" + std::to_string(i));
    }
    write_trajectory(dir / "t.txt", t);
    const Trajectory back = read_trajectory(dir / "t.txt");
    ASSERT_EQ(back.format, f);
    ASSERT_EQ(back.size(), 5u);
    for (int i = 0; i < 5; ++i) {
      EXPECT_LT(test::translation_error(back.poses[i], t.poses[i]), 1e-6);
      EXPECT_LT(test::rotation_error_deg(back.poses[i], t.poses[i]), 1e-5);
    }
    if (f == TrajectoryFormat::tum) EXPECT_NEAR(back.stamps[3], 0.3, 1e-9);
    if (f == TrajectoryFormat::named) EXPECT_EQ(back.names[2], "v2");
  }
  write_bytes(dir / "bad.txt", "1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0 0 0 1 0 nan 0 0 1 0\n");
  try {
    read_trajectory(dir / "bad.txt");
    ADD_FAILURE();
  } catch (const Error& e) { EXPECT_NE(std::string(e.what()).find("bad.txt:2"), std::string::npos) << e.what(); }
  write_bytes(dir / "mixed.txt", "1 0 0 0 0 1 0 0 0 0 1 0\n0 1 2 3 0 0 0 1\n");
  EXPECT_THROW(read_trajectory(dir / "mixed.txt"), Error);
  write_bytes(dir / "empty.txt", "# nothing\n");
  EXPECT_THROW(read_trajectory(dir / "empty.txt"), Error);
  // Finite numbers that are no pose: a scaled rotation block, an overflowing quaternion.
  write_bytes(dir / "scaled.txt", "2 0 0 0 0 2 0 0 0 0 2 0\n");
  EXPECT_THROW(read_trajectory(dir / "scaled.txt"), Error);
  write_bytes(dir / "quat.txt", "0 1 2 3 1e200 0 0 1e200\n");
  EXPECT_THROW(read_trajectory(dir / "quat.txt"), Error);
}

TEST(TrajectoryIO, ReadsRealKittiGroundTruth) {
  GCMAP_REQUIRE_SHARED_DATA("kitti00_gt");
  const Trajectory gt = read_trajectory(test::shared_data() + "/kitti00_gt/00.txt");
  EXPECT_EQ(gt.size(), 4541u);
  EXPECT_EQ(gt.format, TrajectoryFormat::kitti);
  const Eigen::Isometry3d Tr = read_kitti_calib_tr(test::shared_data() + "/kitti00_gt/calib.txt");
  EXPECT_NEAR(Tr.linear().determinant(), 1.0, 1e-6);
}

TEST(AtomicWrite, FailureLeavesNoFileAndNamesThePath) {
  test::TempDir dir;
  const std::string path = dir / "out.txt";
  EXPECT_THROW(write_file_atomic(path, [](std::ostream&) { throw Error("boom"); }), Error);
  EXPECT_FALSE(std::filesystem::exists(path));
  EXPECT_TRUE(std::filesystem::is_empty(dir.path));
  try {
    write_file_atomic(dir / "no/such/dir/x.txt", [](std::ostream& o) { o << 1; });
    ADD_FAILURE();
  } catch (const Error& e) { EXPECT_NE(std::string(e.what()).find("no/such/dir/x.txt"), std::string::npos); }
}

}  // namespace
}  // namespace gcmap
