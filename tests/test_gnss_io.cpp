#include <cmath>
#include <fstream>
#include <sstream>

#include "gcmap/core/error.hpp"
#include "gcmap/io/gnss_io.hpp"
#include "test_util.hpp"

namespace gcmap {
namespace {

TEST(GnssIo, RoundTrip) {
  test::TempDir dir;
  std::vector<GnssFix> fixes = {{0.0, {48.1, 11.5, 520.25}, {0.015, 0.015, 0.025}},
                                {0.1, {-33.868812345, 151.2093, -12.5}, {2.0, 2.5, 3.0}}};
  write_gnss_txt(dir / "gnss.txt", fixes);
  const std::vector<GnssFix> back = read_gnss_txt(dir / "gnss.txt");
  ASSERT_EQ(back.size(), fixes.size());
  for (size_t k = 0; k < fixes.size(); ++k) {
    EXPECT_NEAR(back[k].stamp, fixes[k].stamp, 1e-6);
    // 1e-10 degrees is about 11 micrometres.
    EXPECT_NEAR(back[k].position.lat_deg, fixes[k].position.lat_deg, 1e-10);
    EXPECT_NEAR(back[k].position.lon_deg, fixes[k].position.lon_deg, 1e-10);
    EXPECT_NEAR(back[k].position.alt_m, fixes[k].position.alt_m, 1e-4);
    EXPECT_LT((back[k].sigma_enu - fixes[k].sigma_enu).norm(), 1e-4);
  }
}

// The error names the file and line of the first bad line and what is wrong there.
void expect_error(const std::string& text, const std::string& line, const std::string& what) {
  test::TempDir dir;
  std::ofstream(dir / "gnss.txt") << text;
  try {
    read_gnss_txt(dir / "gnss.txt");
    ADD_FAILURE() << "no error for:\n" << text;
  } catch (const Error& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find(dir / "gnss.txt" + ":" + line + ":"), std::string::npos) << m;
    EXPECT_NE(m.find(what), std::string::npos) << m;
    EXPECT_EQ(m.find('\n'), std::string::npos) << m;
  }
}

TEST(GnssIo, BadLinesAreErrorsNamingFileAndLine) {
  const std::string good = "# stamp lat lon alt se sn su\n0 48 11 500 0.1 0.1 0.2\n";
  expect_error(good + "1 95 11 500 0.1 0.1 0.2\n", "3", "latitude");
  expect_error(good + "1 48 181 500 0.1 0.1 0.2\n", "3", "longitude");
  expect_error(good + "1 48 11 500 0 0.1 0.2\n", "3", "sigmas");
  expect_error(good + "1 48 11 500 0.1 0.1\n", "3", "6 values, expected 7");
  expect_error(good + "1 48 11 500 0.1 0.1 0.2 9\n", "3", "more than 7");
  expect_error(good + "1 48 11 nan 0.1 0.1 0.2\n", "3", "not a finite number");
  expect_error(good + "0 48 11 500 0.1 0.1 0.2\n", "3", "not after the line before");
  test::TempDir dir;
  std::ofstream(dir / "empty.txt") << "# only a comment\n";
  EXPECT_THROW(read_gnss_txt(dir / "empty.txt"), Error);
}

std::vector<Eigen::Vector3d> read_columns(const std::string& path, int first) {
  std::ifstream in(path);
  std::vector<Eigen::Vector3d> out;
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream ss(line);
    double v[8];
    for (double& x : v) ss >> x;
    out.emplace_back(v[first], v[first + 1], v[first + 2]);
  }
  return out;
}

TEST(GnssIo, UtmAndWgs84TrajectoriesAgreeWithProj) {
  test::TempDir dir;
  const Geodetic origin{48.137154, 11.576124, 520.0};  // 1.6 deg east of zone 32's central meridian
  std::vector<Eigen::Isometry3d> poses(3, Eigen::Isometry3d::Identity());
  poses[1].translation() << 1000.0, 0.0, 5.0;
  poses[2].translation() << 0.0, -2000.0, -3.0;
  poses[2].linear() = Eigen::AngleAxisd(0.7, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  const std::vector<double> stamps = {0.0, 1.0, 2.0};
  const int epsg = utm_epsg(origin);
  ASSERT_EQ(epsg, 32632);
  write_trajectory_utm(dir / "utm.txt", origin, epsg, stamps, poses);
  write_trajectory_wgs84(dir / "wgs84.txt", origin, stamps, poses);
  const std::vector<Eigen::Vector3d> utm = read_columns(dir / "utm.txt", 1), geo = read_columns(dir / "wgs84.txt", 1);
  const CrsTransform proj(epsg);
  const Eigen::Isometry3d T = T_ecef_enu(origin);
  for (size_t k = 0; k < poses.size(); ++k) {
    const Eigen::Vector3d p_ecef = T * poses[k].translation();
    EXPECT_LT((utm[k] - proj.from_ecef(p_ecef)).norm(), 2e-4);
    const Geodetic g{geo[k].x(), geo[k].y(), geo[k].z()};
    EXPECT_LT((ecef_from_geodetic(g) - p_ecef).norm(), 1e-3);
  }
  // East of the central meridian the meridians lean towards it going north: true north points west
  // of grid north by the convergence, about dlon sin(lat) (1.9 deg here).
  const Eigen::Matrix3d R = R_grid_enu(proj, origin);
  const Eigen::Vector3d north = R * Eigen::Vector3d::UnitY();
  const double convergence_deg = std::atan2(north.x(), north.y()) * 180.0 / M_PI;
  EXPECT_NEAR(convergence_deg, -std::sin(origin.lat_deg * M_PI / 180.0) * (origin.lon_deg - 9.0), 0.02);
  // A metre east in ENU lands where PROJ puts it.
  const Eigen::Vector3d a = proj.from_ecef(T.translation()), b = proj.from_ecef(T * Eigen::Vector3d(1, 0, 0));
  EXPECT_LT(((b - a).normalized() - R * Eigen::Vector3d::UnitX()).norm(), 1e-6);
}

}  // namespace
}  // namespace gcmap
