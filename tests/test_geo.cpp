#include <cstdio>
#include <cstdlib>

#include "gcmap/core/error.hpp"
#include "gcmap/io/geo.hpp"
#include "test_util.hpp"

namespace gcmap {
namespace {

double ecef_distance(const Geodetic& a, const Geodetic& b) { return (ecef_from_geodetic(a) - ecef_from_geodetic(b)).norm(); }

const std::vector<Geodetic> kPlaces = {{49.0, 8.0, 100.0},        {48.137, 11.575, 520.0}, {-33.8688, 151.2093, 20.0},
                                       {35.6812, 139.7671, 40.0}, {-54.8, -68.3, 0.0},     {64.1466, -21.9426, 30.0},
                                       {0.001, -0.001, -30.0}};

TEST(Geo, EcefRoundTripBelowAMicrometre) {
  for (const Geodetic& g : kPlaces) {
    const Geodetic back = geodetic_from_ecef(ecef_from_geodetic(g));
    EXPECT_LT(ecef_distance(g, back), 1e-6) << g.lat_deg << " " << g.lon_deg;
    EXPECT_NEAR(back.alt_m, g.alt_m, 1e-6);
  }
}

TEST(Geo, EnuAxesPointEastNorthUp) {
  const Geodetic o{49.0, 8.0, 100.0};
  const Eigen::Isometry3d T = T_ecef_enu(o);
  EXPECT_LT((T.linear().transpose() * T.linear() - Eigen::Matrix3d::Identity()).norm(), 1e-12);
  EXPECT_NEAR(T.linear().determinant(), 1.0, 1e-12);
  const Geodetic up = geodetic_from_ecef(T * Eigen::Vector3d(0, 0, 50));
  EXPECT_NEAR(up.alt_m, 150.0, 1e-6);
  const Geodetic east = geodetic_from_ecef(T * Eigen::Vector3d(100, 0, 0));
  const Geodetic north = geodetic_from_ecef(T * Eigen::Vector3d(0, 100, 0));
  EXPECT_GT(east.lon_deg, o.lon_deg);
  EXPECT_NEAR(east.lat_deg, o.lat_deg, 1e-5);
  EXPECT_NEAR((north.lat_deg - o.lat_deg) * 111200.0, 100.0, 0.5);  // about 111.2 km per degree at 49 N
}

TEST(Geo, UtmZoneChosenFromThePosition) {
  EXPECT_EQ(utm_epsg({48.137, 11.575, 0}), 32632);      // Munich
  EXPECT_EQ(utm_epsg({-33.8688, 151.2093, 0}), 32756);  // Sydney
  EXPECT_EQ(utm_epsg({60.39, 5.32, 0}), 32632);         // Bergen: Norway's exception (else 31)
  EXPECT_EQ(utm_epsg({78.22, 15.65, 0}), 32633);        // Longyearbyen: Svalbard's
  EXPECT_EQ(utm_epsg({10.0, 180.0, 0}), 32601);
  EXPECT_EQ(utm_name(32632), "32N");
  EXPECT_EQ(utm_name(32756), "56S");
}

TEST(Geo, Wgs84ToUtmAndBackWithinAMillimetre) {
  for (const Geodetic& g : kPlaces) {
    const CrsTransform utm(utm_epsg(g));
    const Eigen::Vector3d p = utm.from_geodetic(g);
    EXPECT_NEAR(p.z(), g.alt_m, 1e-6) << "the ellipsoidal height passes through";
    EXPECT_LT(ecef_distance(utm.to_geodetic(p), g), 1e-3) << g.lat_deg << " " << g.lon_deg;
  }
}

// What PROJ's own command-line tool says for a point: cs2cs when installed (proj-bin), else the
// values it printed when this test was written (cs2cs 9.1.1).
Eigen::Vector3d cs2cs(const std::string& from, const std::string& to, const std::string& input, const Eigen::Vector3d& recorded) {
  if (std::system("command -v cs2cs >/dev/null 2>&1") != 0) return recorded;
  test::TempDir tmp;
  const std::string cmd = "echo '" + input + "' | cs2cs -f %.4f " + from + " " + to + " > " + (tmp / "out");
  if (std::system(cmd.c_str()) != 0) return recorded;
  Eigen::Vector3d v;
  std::FILE* f = std::fopen((tmp / "out").c_str(), "r");
  const int n = std::fscanf(f, "%lf %lf %lf", &v.x(), &v.y(), &v.z());
  std::fclose(f);
  return n == 3 ? v : recorded;
}

TEST(Geo, KnownPointsAgreeWithCs2cs) {
  const CrsTransform utm32(32632), utm56(32756), ecef(4978);
  const Eigen::Vector3d a = cs2cs("EPSG:4979", "EPSG:32632", "49 8 100", {426857.9877, 5427937.5235, 100.0});
  EXPECT_LT((utm32.from_geodetic({49.0, 8.0, 100.0}) - a).norm(), 2e-4);
  const Eigen::Vector3d b = cs2cs("EPSG:4979", "EPSG:32756", "-33.8688 151.2093 20", {334368.6336, 6250948.3454, 20.0});
  EXPECT_LT((utm56.from_geodetic({-33.8688, 151.2093, 20.0}) - b).norm(), 2e-4);
  const Eigen::Vector3d c = cs2cs("EPSG:4979", "EPSG:4978", "49 8 100", {4151699.4173, 583483.3015, 4790634.2184});
  EXPECT_LT((ecef_from_geodetic({49.0, 8.0, 100.0}) - c).norm(), 2e-4);
  EXPECT_LT((ecef.from_geodetic({49.0, 8.0, 100.0}) - c).norm(), 2e-4);
  EXPECT_NE(utm32.wkt().find("UTM zone 32N"), std::string::npos);
  EXPECT_EQ(utm32.wkt().rfind("PROJCS[", 0), 0u);
  EXPECT_EQ(utm32.name(), "WGS 84 / UTM zone 32N");
}

TEST(Geo, BadInputGivesOneLineErrors) {
  EXPECT_EQ(parse_crs("EPSG:25832"), 25832);
  EXPECT_EQ(parse_crs("utm"), 0);
  EXPECT_THROW(parse_crs("EPSG:"), Error);
  EXPECT_THROW(parse_crs("EPSG:12x"), Error);
  EXPECT_THROW(parse_crs("WGS84"), Error);
  EXPECT_THROW(CrsTransform(999999), Error);
  const Geodetic g = parse_geodetic("--origin", "49.5,8.25,-12");
  EXPECT_EQ(g.lat_deg, 49.5);
  EXPECT_EQ(g.lon_deg, 8.25);
  EXPECT_EQ(g.alt_m, -12.0);
  try {
    parse_geodetic("--origin", "95,8,0");
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()).rfind("--origin: latitude must lie in [-90, 90]", 0), 0u) << e.what();
  }
  EXPECT_THROW(parse_geodetic("--origin", "49,8"), Error);
  EXPECT_THROW(parse_geodetic("--origin", "49,8,0,1"), Error);
  EXPECT_THROW(parse_geodetic("--origin", "49;8;0"), Error);
}

}  // namespace
}  // namespace gcmap
