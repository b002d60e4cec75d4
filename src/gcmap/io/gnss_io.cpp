#include "gcmap/io/gnss_io.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <optional>
#include <sstream>

#include "gcmap/core/error.hpp"
#include "gcmap/io/file.hpp"

namespace gcmap {

namespace {

bool to_double(const std::string& s, double& v) {
  const auto r = std::from_chars(s.data(), s.data() + s.size(), v);
  return r.ec == std::errc() && r.ptr == s.data() + s.size() && std::isfinite(v);
}

constexpr const char* kFields = "stamp latitude longitude altitude sigma_east sigma_north sigma_up";

void check_ranges(const GnssFix& f, const std::string& where) {
  if (std::abs(f.position.lat_deg) > 90.0)
    throw Error(where + ": latitude " + std::to_string(f.position.lat_deg) + " is beyond +-90 degrees");
  if (std::abs(f.position.lon_deg) > 180.0)
    throw Error(where + ": longitude " + std::to_string(f.position.lon_deg) + " is beyond +-180 degrees");
  if (!(f.sigma_enu.minCoeff() > 0.0)) throw Error(where + ": the sigmas must be > 0 m");
}

GnssFix parse_line(const std::string& line, const std::string& where) {
  std::istringstream ss(line);
  std::string t;
  double v[7];
  int n = 0;
  while (ss >> t) {
    if (n == 7) throw Error(where + ": more than 7 values (expected: " + kFields + ")");
    if (!to_double(t, v[n])) throw Error(where + ": '" + t + "' is not a finite number");
    ++n;
  }
  if (n != 7) throw Error(where + ": " + std::to_string(n) + " values, expected 7 (" + kFields + ")");
  GnssFix f{v[0], {v[1], v[2], v[3]}, {v[4], v[5], v[6]}};
  check_ranges(f, where);
  return f;
}

// sigma_east, sigma_north, sigma_up from the diagonal; none when the driver gave no usable covariance.
std::optional<Eigen::Vector3d> covariance_sigma(const NavSatFixMsg& m) {
  if (m.covariance_type == NavSatCovariance::unknown) return std::nullopt;
  const Eigen::Vector3d var(m.position_covariance[0], m.position_covariance[4], m.position_covariance[8]);
  if (!(var.minCoeff() > 0.0) || !var.allFinite()) return std::nullopt;
  return var.cwiseSqrt();
}

bool has_fix(const NavSatFixMsg& m) {
  return int(m.status) >= int(NavSatStatus::fix) && std::isfinite(m.latitude) && std::isfinite(m.longitude) &&
         std::isfinite(m.altitude);
}

// Unit quaternion as "qx qy qz qw".
void print_quaternion(char* buf, size_t size, const Eigen::Matrix3d& R) {
  const Eigen::Quaterniond q(R);
  std::snprintf(buf, size, "%.9f %.9f %.9f %.9f", q.x(), q.y(), q.z(), q.w());
}

}  // namespace

std::vector<GnssFix> read_gnss_txt(const std::string& path) { return parse_gnss_txt(read_file(path), path); }

std::vector<GnssFix> parse_gnss_txt(std::string_view text, const std::string& path) {
  std::istringstream in{std::string(text)};
  std::vector<GnssFix> fixes;
  std::string line;
  for (int number = 1; std::getline(in, line); ++number) {
    const size_t first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos || line[first] == '#') continue;
    const std::string where = path + ":" + std::to_string(number);
    fixes.push_back(parse_line(line, where));
    if (fixes.size() > 1 && !(fixes.back().stamp > fixes[fixes.size() - 2].stamp))
      throw Error(where + ": stamp " + std::to_string(fixes.back().stamp) + " is not after the line before");
  }
  if (fixes.empty()) throw Error(path + ": no GNSS fixes (expected lines of: " + kFields + ")");
  return fixes;
}

std::string GnssTopic::describe(const std::string& source, const Eigen::Vector3d& fallback_sigma) const {
  char buf[384];
  std::snprintf(buf, sizeof(buf), "%zu fixes from %s; %zu epochs without a fix skipped", fixes.size(), source.c_str(), no_fix);
  std::string s = buf;
  if (unknown_covariance > 0) {
    std::snprintf(buf, sizeof(buf), "; %zu fixes without a covariance taken at sigma %.2g m east, %.2g m north, %.2g m up",
                  unknown_covariance, fallback_sigma.x(), fallback_sigma.y(), fallback_sigma.z());
    s += buf;
  }
  if (duplicates > 0) s += "; " + std::to_string(duplicates) + " repeated stamps dropped";
  return s;
}

std::vector<std::string> gnss_topics(const BagReader& bag) {
  std::vector<std::string> names;
  for (const BagTopic& t : bag.topics())
    if (is_navsatfix_type(t.type)) names.push_back(t.name);
  return names;
}

GnssTopic read_bag_gnss(BagReader& bag, const std::string& topic, const Eigen::Vector3d& fallback_sigma) {
  const BagTopic& t = bag.topic(topic);
  const std::string where = bag.path() + ": topic " + topic;
  if (!is_navsatfix_type(t.type)) throw Error(where + " is " + t.type + ", not sensor_msgs/NavSatFix");
  GnssTopic out;
  auto cursor = bag.read(topic);
  BagMessage msg;
  while (cursor->next(msg)) {
    const std::string at = where + ", message at " + std::to_string(msg.time_ns) + " ns";
    const NavSatFixMsg m = decode_navsatfix(msg.data, t.encoding, at);
    if (!has_fix(m)) {
      ++out.no_fix;
      continue;
    }
    const std::optional<Eigen::Vector3d> sigma = covariance_sigma(m);
    if (!sigma) ++out.unknown_covariance;
    GnssFix f{double(m.stamp_ns) * 1e-9, {m.latitude, m.longitude, m.altitude}, sigma.value_or(fallback_sigma)};
    check_ranges(f, at);
    out.fixes.push_back(f);
  }
  if (out.fixes.empty()) throw Error(where + ": no message with a fix (" + std::to_string(out.no_fix) + " without)");
  // Record order is not stamp order where drivers buffer.
  std::stable_sort(out.fixes.begin(), out.fixes.end(), [](const GnssFix& a, const GnssFix& b) { return a.stamp < b.stamp; });
  const size_t before = out.fixes.size();
  out.fixes.erase(
      std::unique(out.fixes.begin(), out.fixes.end(), [](const GnssFix& a, const GnssFix& b) { return a.stamp == b.stamp; }),
      out.fixes.end());
  out.duplicates = before - out.fixes.size();
  return out;
}

void write_gnss_txt(const std::string& path, const std::vector<GnssFix>& fixes) {
  write_file_atomic(path, [&](std::ostream& out) {
    out << "# stamp[s] latitude longitude[deg WGS84] altitude[m ellipsoidal] sigma_east sigma_north sigma_up[m]\n";
    char buf[256];
    for (const GnssFix& f : fixes) {
      std::snprintf(buf, sizeof(buf), "%.6f %.10f %.10f %.4f %.4f %.4f %.4f\n", f.stamp, f.position.lat_deg, f.position.lon_deg,
                    f.position.alt_m, f.sigma_enu.x(), f.sigma_enu.y(), f.sigma_enu.z());
      out << buf;
    }
  });
}

Eigen::Vector3d enu_from_geodetic(const Geodetic& origin, const Geodetic& g) {
  return T_ecef_enu(origin).inverse() * ecef_from_geodetic(g);
}

Eigen::Matrix3d R_enu_at(const Geodetic& g, const Geodetic& origin) {
  return T_ecef_enu(g).linear().transpose() * T_ecef_enu(origin).linear();
}

Eigen::Matrix3d R_grid_enu(const CrsTransform& utm, const Geodetic& g) {
  // Grid north is where 1 m of true north goes; the rotation takes true north onto it.
  const Eigen::Isometry3d T = T_ecef_enu(g);
  const Eigen::Vector3d a = utm.from_ecef(T.translation()), b = utm.from_ecef(T * Eigen::Vector3d(0.0, 1.0, 0.0));
  const double angle = std::atan2(-(b.x() - a.x()), b.y() - a.y());
  return Eigen::AngleAxisd(angle, Eigen::Vector3d::UnitZ()).toRotationMatrix();
}

void write_trajectory_utm(const std::string& path, const Geodetic& origin, int epsg, const std::vector<double>& stamps,
                          const std::vector<Eigen::Isometry3d>& T_enu_frame) {
  if (stamps.size() != T_enu_frame.size()) throw Error(path + ": " + std::to_string(stamps.size()) + " stamps for poses");
  const CrsTransform utm(epsg);
  const Eigen::Isometry3d T_ecef = T_ecef_enu(origin);
  write_file_atomic(path, [&](std::ostream& out) {
    char buf[256], q[128];
    for (size_t k = 0; k < stamps.size(); ++k) {
      const Eigen::Vector3d p_ecef = T_ecef * T_enu_frame[k].translation();
      const Geodetic g = geodetic_from_ecef(p_ecef);
      const Eigen::Vector3d p = utm.from_ecef(p_ecef);
      print_quaternion(q, sizeof(q), R_grid_enu(utm, g) * R_enu_at(g, origin) * T_enu_frame[k].linear());
      std::snprintf(buf, sizeof(buf), "%.6f %.4f %.4f %.4f %s\n", stamps[k], p.x(), p.y(), p.z(), q);
      out << buf;
    }
  });
}

void write_trajectory_wgs84(const std::string& path, const Geodetic& origin, const std::vector<double>& stamps,
                            const std::vector<Eigen::Isometry3d>& T_enu_frame) {
  if (stamps.size() != T_enu_frame.size()) throw Error(path + ": " + std::to_string(stamps.size()) + " stamps for poses");
  const Eigen::Isometry3d T_ecef = T_ecef_enu(origin);
  write_file_atomic(path, [&](std::ostream& out) {
    out << "# stamp[s] latitude longitude[deg WGS84] altitude[m ellipsoidal] qx qy qz qw (sensor orientation in the local "
           "ENU frame at the pose)\n";
    char buf[256], q[128];
    for (size_t k = 0; k < stamps.size(); ++k) {
      const Geodetic g = geodetic_from_ecef(T_ecef * T_enu_frame[k].translation());
      print_quaternion(q, sizeof(q), R_enu_at(g, origin) * T_enu_frame[k].linear());
      std::snprintf(buf, sizeof(buf), "%.6f %.10f %.10f %.4f %s\n", stamps[k], g.lat_deg, g.lon_deg, g.alt_m, q);
      out << buf;
    }
  });
}

}  // namespace gcmap
