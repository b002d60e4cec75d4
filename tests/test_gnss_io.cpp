#include <cmath>
#include <fstream>
#include <sstream>

#include "bag_test_util.hpp"
#include "gcmap/core/error.hpp"
#include "gcmap/io/bag_writer.hpp"
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

// --- sensor_msgs/NavSatFix from bags ---

NavSatFixMsg fix_message(int64_t stamp_ns, double lat, double lon, double alt, const Eigen::Vector3d& sigma) {
  NavSatFixMsg m;
  m.stamp_ns = stamp_ns;
  m.frame_id = "gps";
  m.status = NavSatStatus::gbas_fix;
  m.service = 9;
  m.latitude = lat;
  m.longitude = lon;
  m.altitude = alt;
  for (int a = 0; a < 3; ++a) m.position_covariance[4 * a] = sigma[a] * sigma[a];
  m.position_covariance[1] = m.position_covariance[3] = 0.25;  // off-diagonal terms are read past
  m.covariance_type = NavSatCovariance::known;
  return m;
}

TEST(GnssIo, NavSatFixMessagesRoundTripInBothEncodings) {
  NavSatFixMsg m = fix_message(1700000000123456789, 48.137154321, -11.576124987, 520.125, {0.02, 0.03, 0.05});
  m.status = NavSatStatus::no_fix;
  for (MessageEncoding enc : {MessageEncoding::ros1, MessageEncoding::cdr}) {
    const NavSatFixMsg back = decode_navsatfix(encode_navsatfix(m, enc), enc, "test");
    EXPECT_EQ(back.stamp_ns, m.stamp_ns);
    EXPECT_EQ(back.frame_id, m.frame_id);
    EXPECT_EQ(back.status, m.status);
    EXPECT_EQ(back.service, m.service);
    EXPECT_EQ(back.latitude, m.latitude);
    EXPECT_EQ(back.longitude, m.longitude);
    EXPECT_EQ(back.altitude, m.altitude);
    EXPECT_EQ(back.position_covariance, m.position_covariance);
    EXPECT_EQ(back.covariance_type, m.covariance_type);
  }
  // The ROS 1 layout is packed: header (4 + 8 + 4 + 3), status 1 + 2, 3 doubles, 9 doubles, type 1.
  EXPECT_EQ(encode_navsatfix(m, MessageEncoding::ros1).size(), 19u + 3u + 24u + 72u + 1u);
  const std::string cdr = encode_navsatfix(m, MessageEncoding::cdr);
  EXPECT_THROW(decode_navsatfix(cdr.substr(0, cdr.size() - 2), MessageEncoding::cdr, "cut"), Error);
}

// A driver's topic: fixes with and without a covariance, NO_FIX epochs, one NaN position, one
// repeated stamp, written out of order.
void write_fix_bag(const std::string& path, const test::Container& c) {
  auto w = open_bag_writer(path, c.format, c.options);
  const uint32_t topic = w->add_topic("/fix", "sensor_msgs/msg/NavSatFix");
  std::vector<NavSatFixMsg> messages;
  for (int k = 0; k < 12; ++k)
    messages.push_back(fix_message(1000000000LL * (100 + k), 48.1 + 1e-5 * k, 11.5, 520.0 + k, {0.02, 0.03, 0.05 + 0.01 * k}));
  messages[3].status = NavSatStatus::no_fix;
  messages[4].status = NavSatStatus::unknown;
  messages[5].latitude = std::nan("");
  messages[6].covariance_type = NavSatCovariance::unknown;
  messages[7].position_covariance[8] = 0.0;  // a driver's "unknown" spelled as zeros
  messages.push_back(messages[9]);           // the same epoch twice
  std::swap(messages[10], messages[11]);
  for (const NavSatFixMsg& m : messages) w->write(topic, m.stamp_ns, encode_navsatfix(m, message_encoding(c.format)));
  w->close();
}

TEST(GnssIo, NavSatFixTopicsReadInEveryContainer) {
  const Eigen::Vector3d fallback(3.0, 3.0, 5.0);
  for (const test::Container& c : test::containers()) {
    test::TempDir dir;
    const std::string path = dir / test::bag_name(c);
    write_fix_bag(path, c);
    auto bag = open_bag(path);
    ASSERT_EQ(gnss_topics(*bag), std::vector<std::string>{"/fix"}) << c.name;
    const GnssTopic t = read_bag_gnss(*bag, "/fix", fallback);
    EXPECT_EQ(t.no_fix, 3u) << c.name;
    EXPECT_EQ(t.unknown_covariance, 2u) << c.name;
    EXPECT_EQ(t.duplicates, 1u) << c.name;
    ASSERT_EQ(t.fixes.size(), 9u) << c.name;  // 12 epochs, 3 without a fix
    const std::vector<int> epochs = {0, 1, 2, 6, 7, 8, 9, 10, 11};
    for (size_t k = 0; k < epochs.size(); ++k) {
      const int e = epochs[k];
      EXPECT_NEAR(t.fixes[k].stamp, 100.0 + e, 1e-9) << c.name;
      EXPECT_EQ(t.fixes[k].position.lat_deg, 48.1 + 1e-5 * e) << c.name;
      EXPECT_EQ(t.fixes[k].position.alt_m, 520.0 + e) << c.name;
      const Eigen::Vector3d sigma = e == 6 || e == 7 ? fallback : Eigen::Vector3d(0.02, 0.03, 0.05 + 0.01 * e);
      EXPECT_LT((t.fixes[k].sigma_enu - sigma).norm(), 1e-12) << c.name << " epoch " << e;
    }
    const std::string said = t.describe("/fix", fallback);
    EXPECT_NE(said.find("3 epochs without a fix skipped"), std::string::npos) << said;
    EXPECT_NE(said.find("2 fixes without a covariance taken at sigma 3 m east"), std::string::npos) << said;
  }
}

TEST(GnssIo, NavSatFixErrorsNameTheBagTopicAndMessage) {
  test::TempDir dir;
  auto w = open_bag_writer(dir / "gps.mcap", BagFormat::mcap);
  const uint32_t fix = w->add_topic("/fix", "sensor_msgs/msg/NavSatFix");
  const uint32_t lost = w->add_topic("/lost", "sensor_msgs/msg/NavSatFix");
  const uint32_t cut = w->add_topic("/cut", "sensor_msgs/msg/NavSatFix");
  w->write(fix, 5, encode_navsatfix(fix_message(5, 91.0, 11.5, 520.0, Eigen::Vector3d::Ones()), MessageEncoding::cdr));
  NavSatFixMsg none = fix_message(6, 48.0, 11.5, 520.0, Eigen::Vector3d::Ones());
  none.status = NavSatStatus::no_fix;
  w->write(lost, 6, encode_navsatfix(none, MessageEncoding::cdr));
  w->write(cut, 7, encode_navsatfix(none, MessageEncoding::cdr).substr(0, 30));
  w->close();
  auto bag = open_bag(dir / "gps.mcap");
  const auto expect = [&](const std::string& topic, const std::string& needle) {
    try {
      read_bag_gnss(*bag, topic, Eigen::Vector3d::Ones());
      ADD_FAILURE() << topic << ": no error";
    } catch (const Error& e) {
      const std::string m = e.what();
      EXPECT_NE(m.find(dir / "gps.mcap"), std::string::npos) << m;
      EXPECT_NE(m.find(needle), std::string::npos) << m;
    }
  };
  expect("/fix", "topic /fix, message at 5 ns: latitude 91");
  expect("/lost", "topic /lost: no message with a fix (1 without)");
  expect("/cut", "topic /cut, message at 7 ns");
}

}  // namespace
}  // namespace gcmap
