#include <cmath>
#include <cstdlib>
#include <fstream>
#include <sstream>

#include "gcmap/core/error.hpp"
#include "gcmap/io/las.hpp"
#include "test_util.hpp"

namespace gcmap {
namespace {

// Every channel filled, around a UTM-sized offset so that float coordinates would lose the mm;
// with `colors`, point format 7.
LasCloud sample_las(size_t n, bool colors = false) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-300.0, 300.0);
  LasCloud c;
  for (size_t i = 0; i < n; ++i) {
    c.points.emplace_back(426858.0 + u(rng), 5427937.0 + u(rng), 110.0 + 0.1 * u(rng));
    c.intensities.push_back(static_cast<uint16_t>(i * 37));
    c.gps_times.push_back(1.7e9 + 0.001 * i);
    c.classes.push_back(static_cast<uint8_t>(i % 23));
    c.point_source_ids.push_back(static_cast<uint16_t>(i / 100));
    if (colors) c.colors.push_back({uint16_t(i * 65), uint16_t(65535 - i), uint16_t(i * 7919)});
  }
  return c;
}

double stored(double value, double offset) { return std::llround((value - offset) / kLasScale) * kLasScale + offset; }

void expect_same_points(const LasCloud& written, const LasFile& read) {
  ASSERT_EQ(read.cloud.size(), written.size());
  for (size_t i = 0; i < written.size(); ++i) {
    for (int k = 0; k < 3; ++k) {
      ASSERT_NEAR(read.cloud.points[i][k], written.points[i][k], 0.5 * kLasScale + 1e-9);
      ASSERT_DOUBLE_EQ(read.cloud.points[i][k], stored(written.points[i][k], read.header.offset[k]));
    }
    ASSERT_EQ(read.cloud.intensities[i], written.intensities[i]);
    ASSERT_EQ(read.cloud.gps_times[i], written.gps_times[i]);
    ASSERT_EQ(read.cloud.classes[i], written.classes[i]);
    ASSERT_EQ(read.cloud.point_source_ids[i], written.point_source_ids[i]);
  }
  EXPECT_EQ(read.cloud.colors, written.colors);
}

TEST(Las, RoundTripKeepsPointsToTheMillimetreAndEveryAttribute) {
  test::TempDir tmp;
  const LasCloud c = sample_las(1000);
  const std::string wkt = "PROJCS[\"WGS 84 / UTM zone 32N\"]";
  write_las(tmp / "a.las", c, {wkt});
  const LasFile f = read_las(tmp / "a.las");
  expect_same_points(c, f);
  EXPECT_EQ(f.header.version_major, 1);
  EXPECT_EQ(f.header.version_minor, 4);
  EXPECT_EQ(f.header.point_format, 6);
  EXPECT_EQ(f.header.record_length, 30);
  EXPECT_EQ(f.header.point_count, 1000u);
  EXPECT_EQ(f.header.points_by_return[0], 1000u);
  EXPECT_EQ(f.header.generating_software.rfind("gcmap", 0), 0u);
  EXPECT_EQ(f.header.wkt, wkt);
  EXPECT_TRUE(f.header.global_encoding & (1 << 4));
  for (const Eigen::Vector3d& p : f.cloud.points) {
    EXPECT_TRUE((p.array() >= f.header.min.array() - 1e-9).all());
    EXPECT_TRUE((p.array() <= f.header.max.array() + 1e-9).all());
  }
  EXPECT_EQ(std::filesystem::file_size(tmp / "a.las"), 375 + 54 + wkt.size() + 1 + 1000 * 30);
}

TEST(Las, ColoursMakePointFormat7AndRoundTrip) {
  test::TempDir tmp;
  const LasCloud c = sample_las(1000, true);
  write_las(tmp / "rgb.las", c);
  const LasFile f = read_las(tmp / "rgb.las");
  expect_same_points(c, f);
  EXPECT_EQ(f.header.point_format, 7);
  EXPECT_EQ(f.header.record_length, 36);
  EXPECT_EQ(std::filesystem::file_size(tmp / "rgb.las"), 375 + 1000 * 36);
  // Tiles keep the colours of their points.
  const std::vector<std::string> tiles = write_las_tiles(tmp.path.string(), "t", c, 400);
  ASSERT_EQ(tiles.size(), 3u);
  EXPECT_EQ(read_las(tiles[2]).cloud.colors.front(), c.colors[800]);
  LasCloud odd = c;
  odd.colors.pop_back();
  EXPECT_THROW(write_las(tmp / "odd.las", odd), Error);
}

TEST(Las, WithoutCrsNoVlrAndEmptyChannelsReadAsZero) {
  test::TempDir tmp;
  LasCloud c;
  c.points = {{1, 2, 3}, {-4, 5.0005, -6}};
  write_las(tmp / "b.las", c);
  const LasFile f = read_las(tmp / "b.las");
  EXPECT_TRUE(f.header.wkt.empty());
  ASSERT_EQ(f.cloud.size(), 2u);
  EXPECT_EQ(f.cloud.intensities[1], 0);
  EXPECT_EQ(f.cloud.classes[1], 0);
  EXPECT_EQ(f.cloud.gps_times[1], 0.0);
  EXPECT_NEAR(f.cloud.points[1].y(), 5.0005, 0.0005 + 1e-9);
  EXPECT_EQ(std::filesystem::file_size(tmp / "b.las"), 375u + 2 * 30);
}

TEST(Las, TilesSplitByPointCountAndTogetherHoldTheMap) {
  test::TempDir tmp;
  const LasCloud c = sample_las(2500);
  const auto paths = write_las_tiles(tmp.path.string(), "map", c, 1000);
  ASSERT_EQ(paths.size(), 3u);
  EXPECT_EQ(paths[0], tmp / "map_000.las");
  EXPECT_EQ(paths[2], tmp / "map_002.las");
  LasCloud all;
  for (const auto& p : paths) append(all, read_las(p).cloud);
  ASSERT_EQ(all.size(), c.size());
  EXPECT_EQ(all.point_source_ids, c.point_source_ids);
  EXPECT_EQ(all.gps_times, c.gps_times);
  for (size_t i = 0; i < c.size(); ++i) ASSERT_LT((all.points[i] - c.points[i]).cwiseAbs().maxCoeff(), 0.5 * kLasScale + 1e-9);
  EXPECT_EQ(write_las_tiles(tmp.path.string(), "small", sample_las(10), 1000), std::vector<std::string>{tmp / "small.las"});
}

TEST(Las, SemanticKittiLabelsBecomeAsprsClasses) {
  EXPECT_EQ(asprs_class_from_semantic_kitti(40), 11);                 // road -> road surface
  EXPECT_EQ(asprs_class_from_semantic_kitti((17u << 16) | 10u), 64);  // car with an instance id
  EXPECT_EQ(asprs_class_from_semantic_kitti(252), 64);                // moving car
  EXPECT_EQ(asprs_class_from_semantic_kitti(50), 6);                  // building
  EXPECT_EQ(asprs_class_from_semantic_kitti(70), 5);                  // vegetation
  EXPECT_EQ(asprs_class_from_semantic_kitti(72), 3);                  // terrain
  EXPECT_EQ(asprs_class_from_semantic_kitti(48), 2);                  // sidewalk
  EXPECT_EQ(asprs_class_from_semantic_kitti(1), 7);                   // outlier -> noise
  EXPECT_EQ(asprs_class_from_semantic_kitti(0), 1);                   // unlabeled
  EXPECT_EQ(asprs_class_from_semantic_kitti(12345), 1);               // unknown

  PointCloud cloud;
  cloud.points = {{1, 0, 0}, {2, 0, 0}};
  cloud.labels = {40, 50};
  cloud.times = {0.0f, 0.05f};
  cloud.intensities = {0.5f, 1.0f};
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Eigen::Vector3d(0, 10, 0);
  const LasCloud las = las_cloud(cloud, T, IntensityScaling::unit, 3, 100.0);
  EXPECT_EQ(las.classes, (std::vector<uint8_t>{11, 6}));
  EXPECT_EQ(las.point_source_ids, (std::vector<uint16_t>{3, 3}));
  EXPECT_DOUBLE_EQ(las.gps_times[1], 100.0 + 0.05f);
  EXPECT_EQ(las.intensities, (std::vector<uint16_t>{32768, 65535}));
  EXPECT_EQ(las.points[1], Eigen::Vector3d(2, 10, 0));
  cloud.labels.clear();
  EXPECT_EQ(las_cloud(cloud, T, IntensityScaling::unit, 0, 0.0).classes, (std::vector<uint8_t>{0, 0}));  // never classified
}

TEST(Las, IntensityScaling) {
  EXPECT_EQ(detect_intensity_scaling({0.0f, 0.3f, 1.0f}), IntensityScaling::unit);
  EXPECT_EQ(detect_intensity_scaling({0.0f, 37.0f, 255.0f}), IntensityScaling::raw);
  EXPECT_EQ(las_intensities({0.0f, 37.4f, 255.0f, 1e6f, -3.0f}, IntensityScaling::raw),
            (std::vector<uint16_t>{0, 37, 255, 65535, 0}));
  EXPECT_THROW(parse_intensity_scaling("percent"), Error);
}

void expect_error(const std::function<void()>& f, const std::string& part) {
  try {
    f();
    FAIL() << "no error; expected one containing \"" << part << "\"";
  } catch (const Error& e) { EXPECT_NE(std::string(e.what()).find(part), std::string::npos) << e.what(); }
}

TEST(Las, BadInputNamesTheFileAndTheProblem) {
  test::TempDir tmp;
  write_las(tmp / "ok.las", sample_las(10));
  const std::string bytes = test::slurp(tmp / "ok.las");
  expect_error([&] { parse_las(bytes.substr(0, bytes.size() - 1), "cut.las"); }, "cut.las: truncated");
  expect_error([&] { parse_las(bytes.substr(0, 200), "head.las"); }, "head.las: truncated header");
  expect_error([&] { parse_las("PK" + bytes.substr(2), "zip.las"); }, "zip.las: not a LAS file");
  std::string v12 = bytes;
  v12[25] = 2;
  expect_error([&] { parse_las(v12, "old.las"); }, "old.las: LAS 1.2, only 1.4 is read");
  std::string f1 = bytes;
  f1[104] = 1;
  expect_error([&] { parse_las(f1, "f1.las"); }, "f1.las: point format 1");
  expect_error([&] { read_las(tmp / "missing.las"); }, "missing.las");

  LasCloud far;
  far.points = {{0, 0, 0}, {5e6, 0, 0}};
  expect_error([&] { write_las(tmp / "far.las", far); }, "far.las: the map spans more than 4294 km");
  LasCloud odd = sample_las(10);
  odd.classes.pop_back();
  expect_error([&] { write_las(tmp / "odd.las", odd); }, "odd.las: a LAS channel's size differs");
  EXPECT_FALSE(std::filesystem::exists(tmp / "odd.las"));
}

// What las_read_copc.js printed against what we wrote (`c`) and read back (`ours`).
void expect_copc_agrees(std::istringstream& in, const LasCloud& c, const LasFile& ours, const std::string& wkt) {
  std::string tag, line;
  int major, minor, format, length;
  size_t count;
  Eigen::Vector3d lo, hi;
  in >> tag >> major >> minor >> format >> length >> count >> lo.x() >> lo.y() >> lo.z() >> hi.x() >> hi.y() >> hi.z();
  EXPECT_EQ(tag, "header");
  EXPECT_EQ(major * 10 + minor, 14);
  EXPECT_EQ(format, c.colors.empty() ? 6 : 7);
  EXPECT_EQ(length, c.colors.empty() ? 30 : 36);
  ASSERT_EQ(count, c.size());
  EXPECT_EQ(lo, ours.header.min);
  EXPECT_EQ(hi, ours.header.max);
  std::getline(in >> std::ws, line);
  EXPECT_EQ(line.rfind("software gcmap", 0), 0u) << line;
  std::getline(in, line);
  EXPECT_EQ(line, "wkt " + wkt);
  for (size_t i = 0; i < c.size(); ++i) {
    double x, y, z, t;
    int intensity, ret, rets, cls, source;
    ASSERT_TRUE(in >> tag >> x >> y >> z >> intensity >> ret >> rets >> cls >> source >> t) << "point " << i;
    EXPECT_NEAR(x, ours.cloud.points[i].x(), 1e-6);  // the same int32 step, scaled in another order
    EXPECT_NEAR(y, ours.cloud.points[i].y(), 1e-6);
    EXPECT_NEAR(z, ours.cloud.points[i].z(), 1e-6);
    EXPECT_LT((Eigen::Vector3d(x, y, z) - c.points[i]).cwiseAbs().maxCoeff(), 0.5 * kLasScale + 1e-6);
    EXPECT_EQ(intensity, c.intensities[i]);
    EXPECT_EQ(ret, 1);
    EXPECT_EQ(rets, 1);
    EXPECT_EQ(cls, c.classes[i]);
    EXPECT_EQ(source, c.point_source_ids[i]);
    EXPECT_EQ(t, c.gps_times[i]);
    if (c.colors.empty()) continue;
    int rgb[3];
    ASSERT_TRUE(in >> rgb[0] >> rgb[1] >> rgb[2]) << "point " << i;
    for (int k = 0; k < 3; ++k) EXPECT_EQ(rgb[k], c.colors[i][k]);
  }
}

// copc (npm) as an independent reader: optional, never downloaded here. To run it:
//   npm install --prefix /tmp/lasjs copc@0.0.8   (or GCMAP_LASJS=DIR for another prefix)
TEST(Las, IndependentReaderAgrees) {
  const char* env = std::getenv("GCMAP_LASJS");
  const std::string prefix = env ? env : "/tmp/lasjs";
  if (std::system("command -v node >/dev/null 2>&1") != 0)
    GTEST_SKIP() << "node is not installed: skipping the independent LAS reader check";
  if (!std::filesystem::exists(prefix + "/node_modules/copc"))
    GTEST_SKIP() << prefix << "/node_modules/copc is absent: skipping the independent LAS reader check "
                 << "(npm install --prefix /tmp/lasjs copc@0.0.8, or set GCMAP_LASJS)";
  for (const bool colors : {false, true}) {
    SCOPED_TRACE(colors ? "format 7" : "format 6");
    test::TempDir tmp;
    const LasCloud c = sample_las(300, colors);
    const std::string wkt = "PROJCS[\"WGS 84 / UTM zone 32N\",AUTHORITY[\"EPSG\",\"32632\"]]";
    write_las(tmp / "a.las", c, {wkt});
    const std::string cmd = "NODE_PATH=" + prefix + "/node_modules node " GCMAP_SOURCE_DIR "/tests/las_read_copc.js " +
                            (tmp / "a.las") + " > " + (tmp / "out") + " 2>&1";
    ASSERT_EQ(std::system(cmd.c_str()), 0) << test::slurp(tmp / "out");
    std::istringstream in(test::slurp(tmp / "out"));
    expect_copc_agrees(in, c, read_las(tmp / "a.las"), wkt);
  }
}

}  // namespace
}  // namespace gcmap
