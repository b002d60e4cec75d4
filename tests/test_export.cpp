// gcmap export on a small hand-made session: what lands in the files, tiles, georeferencing, errors.
#include <cmath>
#include <fstream>

#include "gcmap/io/file.hpp"
#include "gcmap/io/geo.hpp"
#include "gcmap/io/las.hpp"
#include "gcmap/io/point_cloud_io.hpp"
#include "gcmap/io/trajectory_io.hpp"
#include "gcmap/session/session.hpp"
#include "test_util.hpp"

namespace gcmap {
namespace {

Eigen::Isometry3d at(double x, double y, double z, double yaw_deg = 0.0) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(yaw_deg * M_PI / 180.0, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  T.translation() = Eigen::Vector3d(x, y, z);
  return T;
}

// Two submaps of three points; submap 1 sits 100 m east. Frame 1 is at (100, 0, 0) facing north.
const std::vector<Eigen::Vector3f> kPoints = {{0, 0, 0}, {5, 0, 1}, {0, 7, 2}};
const std::vector<Eigen::Vector3d> kWorld = {{0, 0, 0}, {5, 0, 1}, {0, 7, 2}, {100, 0, 0}, {105, 0, 1}, {100, 7, 2}};

// intensities: per point of each submap, or none.
std::string make_output_folder(const test::TempDir& tmp, const std::vector<float>& intensities = {}) {
  Session s;
  s.created_by = "test";
  for (int k = 0; k < 2; ++k) {
    Submap m;
    m.id = k;
    m.keyframes = {k};
    m.T_submap_keyframe = {Eigen::Isometry3d::Identity()};
    auto cloud = std::make_shared<PointCloud>();
    cloud->points = kPoints;
    cloud->covs.assign(kPoints.size(), Eigen::Matrix3f::Identity());
    cloud->intensities = intensities;
    m.cloud = cloud;
    s.submaps.push_back(m);
  }
  s.T_world_submap = {at(0, 0, 0), at(100, 0, 0)};
  s.trajectory = {at(0, 0, 0), at(100, 0, 0, 90.0)};
  s.stamps = {10.0, 10.1};
  const std::string out = tmp / "run";
  write_session(out + "/session", s);
  Trajectory t;
  t.format = TrajectoryFormat::tum;
  t.poses = s.trajectory;
  t.stamps = s.stamps;
  write_trajectory(out + "/trajectory.tum", t);
  return out;
}

TEST(Export, LasFromSessionKeepsPointsAndSubmapIds) {
  test::TempDir tmp;
  const std::string out = make_output_folder(tmp);
  const auto r = test::run_gcmap("export " + out + " -o " + (tmp / "x") + " --quiet");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.err.find("Wrote " + (tmp / "x") + ": map.las, export.json."), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("point source id = submap index"), std::string::npos) << r.err;
  const LasFile f = read_las(tmp / "x/map.las");
  ASSERT_EQ(f.cloud.size(), kWorld.size());
  for (size_t i = 0; i < kWorld.size(); ++i) {
    EXPECT_LT((f.cloud.points[i] - kWorld[i]).norm(), 1e-3);
    EXPECT_EQ(f.cloud.point_source_ids[i], i / 3);
    EXPECT_EQ(f.cloud.classes[i], 0);
  }
  EXPECT_TRUE(f.header.wkt.empty());
  EXPECT_NE(test::slurp(tmp / "x/export.json").find("\"assumptions\":[\"points: every submap cloud"), std::string::npos);
  EXPECT_NE(test::slurp(tmp / "x/export.json").find("intensity: none in the source, written as 0"), std::string::npos);
  EXPECT_FALSE(std::filesystem::exists(tmp / "x/trajectory_wgs84.txt"));
}

TEST(Export, LasFromSessionKeepsItsIntensity) {
  test::TempDir tmp;
  const std::string out = make_output_folder(tmp, {0.0f, 0.25f, 1.0f});
  const auto r = test::run_gcmap("export " + out + " -o " + (tmp / "x") + " --quiet");
  ASSERT_EQ(r.code, 0) << r.err;
  const LasFile f = read_las(tmp / "x/map.las");
  ASSERT_EQ(f.cloud.intensities.size(), kWorld.size());
  const uint16_t scaled[3] = {0, 16384, 65535};  // x 65535, rounded
  for (size_t i = 0; i < kWorld.size(); ++i) EXPECT_EQ(f.cloud.intensities[i], scaled[i % 3]) << i;
  EXPECT_NE(test::slurp(tmp / "x/export.json").find("intensity: values in [0, 1] scaled by 65535"), std::string::npos);
}

TEST(Export, TilesAndNoStaleTilesLeft) {
  test::TempDir tmp;
  const std::string out = make_output_folder(tmp);
  ASSERT_EQ(test::run_gcmap("export " + out + " -o " + (tmp / "x") + " --quiet --max-points 4").code, 0);
  EXPECT_EQ(read_las(tmp / "x/map_000.las").cloud.size(), 4u);
  EXPECT_EQ(read_las(tmp / "x/map_001.las").cloud.size(), 2u);
  EXPECT_FALSE(std::filesystem::exists(tmp / "x/map.las"));
  ASSERT_EQ(test::run_gcmap("export " + out + " -o " + (tmp / "x") + " --quiet").code, 0);
  EXPECT_EQ(read_las(tmp / "x/map.las").cloud.size(), 6u);
  EXPECT_FALSE(std::filesystem::exists(tmp / "x/map_000.las"));
  EXPECT_FALSE(std::filesystem::exists(tmp / "x/map_001.las"));
}

TEST(Export, PlyInTheMapFrame) {
  test::TempDir tmp;
  const std::string out = make_output_folder(tmp);
  ASSERT_EQ(test::run_gcmap("export " + out + " -o " + (tmp / "x") + " --format ply --origin 49,8,100 --quiet").code, 0);
  const PointCloud c = read_point_cloud(tmp / "x/map.ply");
  ASSERT_EQ(c.size(), kWorld.size());
  for (size_t i = 0; i < kWorld.size(); ++i) EXPECT_LT((c.points[i].cast<double>() - kWorld[i]).norm(), 1e-4);
  EXPECT_TRUE(std::filesystem::exists(tmp / "x/trajectory_enu.tum"));
}

double yaw_deg(double qx, double qy, double qz, double qw) {
  const Eigen::Vector3d x = Eigen::Quaterniond(qw, qx, qy, qz).toRotationMatrix().col(0);
  return std::atan2(x.y(), x.x()) * 180.0 / M_PI;
}

std::vector<std::vector<double>> numbers(const std::string& path) {
  std::vector<std::vector<double>> rows;
  std::ifstream in(path);
  for (std::string line; std::getline(in, line);) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream ss(line);
    rows.emplace_back(std::istream_iterator<double>(ss), std::istream_iterator<double>());
  }
  return rows;
}

TEST(Export, GeoreferencedLasAndTrajectories) {
  test::TempDir tmp;
  const std::string out = make_output_folder(tmp);
  const auto r = test::run_gcmap("export " + out + " -o " + (tmp / "x") + " --origin 49,8,100 --crs utm --quiet");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.err.find("WGS 84 / UTM zone 32N (EPSG:32632)"), std::string::npos) << r.err;
  const LasFile f = read_las(tmp / "x/map.las");
  EXPECT_NE(f.header.wkt.find("UTM zone 32N"), std::string::npos);
  // The map origin is the geodetic origin; cs2cs EPSG:4979 EPSG:32632 <<< "49 8 100".
  EXPECT_LT((f.cloud.points[0] - Eigen::Vector3d(426857.9877, 5427937.5235, 100.0)).norm(), 2e-3);
  // Distances survive up to UTM's scale factor (within 0.1 % here); heights rise with the curvature.
  for (size_t i = 1; i < kWorld.size(); ++i) {
    const double d = (f.cloud.points[i] - f.cloud.points[0]).head<2>().norm(), d_map = kWorld[i].head<2>().norm();
    EXPECT_NEAR(d / d_map, 1.0, 1e-3) << i;
  }
  const auto utm = numbers(tmp / "x/trajectory_utm32N.tum");
  ASSERT_EQ(utm.size(), 2u);
  ASSERT_EQ(utm[1].size(), 8u);
  EXPECT_DOUBLE_EQ(utm[1][0], 10.1);
  EXPECT_LT((Eigen::Vector3d(utm[1][1], utm[1][2], utm[1][3]) - f.cloud.points[3]).norm(), 2e-3);
  // Frame 1 faces map north: in grid axes it faces the grid direction from point 3 to point 5.
  const Eigen::Vector3d ahead = f.cloud.points[5] - f.cloud.points[3];
  EXPECT_NEAR(yaw_deg(utm[1][4], utm[1][5], utm[1][6], utm[1][7]), std::atan2(ahead.y(), ahead.x()) * 180 / M_PI, 0.01);
  EXPECT_EQ(numbers(tmp / "x/trajectory_utm32N.kitti").at(1).size(), 12u);
  const auto geo = numbers(tmp / "x/trajectory_wgs84.txt");
  ASSERT_EQ(geo.size(), 2u);
  EXPECT_NEAR(geo[0][1], 49.0, 1e-9);
  EXPECT_NEAR(geo[0][2], 8.0, 1e-9);
  EXPECT_NEAR(geo[0][3], 100.0, 1e-4);
  EXPECT_NEAR(geo[1][1], 49.0, 1e-5);
  EXPECT_NEAR((geo[1][2] - 8.0) * 111320.0 * std::cos(49.0 * M_PI / 180.0), 100.0, 0.5);
  EXPECT_NEAR(yaw_deg(geo[1][4], geo[1][5], geo[1][6], geo[1][7]), 90.0, 0.01);  // north in its local ENU
  EXPECT_EQ(numbers(tmp / "x/trajectory_enu.tum").size(), 2u);
}

void expect_bad_input(const std::string& args, const std::string& message) {
  const auto r = test::run_gcmap("export " + args);
  EXPECT_EQ(r.code, 2) << args;
  EXPECT_NE(r.err.find(message), std::string::npos) << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
}

TEST(Export, BadInputIsOneLineAndExitCode2) {
  test::TempDir tmp;
  const std::string out = make_output_folder(tmp), to = " -o " + (tmp / "x");
  expect_bad_input(tmp / "nowhere" + to, "nowhere: not a folder");
  std::filesystem::create_directories(tmp / "empty");
  expect_bad_input(tmp / "empty" + to, "empty: neither session/ nor map.ply");
  expect_bad_input(out + to + " --crs EPSG:32632", "--crs: needs --origin");
  expect_bad_input(out + to + " --origin 49,8,0 --crs EPSG:32632 --format ply", "--crs: needs --format las");
  expect_bad_input(out + to + " --origin 49,8", "--origin: expected \"LAT,LON,ALT\"");
  expect_bad_input(out + to + " --origin 49,8,0 --crs EPSG:999999", "--crs: PROJ does not know the CRS EPSG:999999");
  expect_bad_input(out + to + " --format laz", "--format: expected las, ply or pcd");
  expect_bad_input(out + to + " --intensity percent", "--intensity: expected unit or raw");
  std::ofstream(out + "/session/submaps.bin", std::ios::trunc) << "GCMAPSM1";
  expect_bad_input(out + to, "submaps.bin");
  EXPECT_FALSE(std::filesystem::exists(tmp / "x/map.las"));
}

}  // namespace
}  // namespace gcmap
