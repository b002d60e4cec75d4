#include "gcmap/io/geo.hpp"

#include <proj.h>

#include <cmath>
#include <mutex>
#include <sstream>

#include "gcmap/core/error.hpp"

namespace gcmap {
namespace {

constexpr double kA = 6378137.0;            // WGS84 semi-major axis (m)
constexpr double kF = 1.0 / 298.257223563;  // flattening
constexpr double kE2 = kF * (2.0 - kF);     // first eccentricity squared
constexpr double kDeg = M_PI / 180.0;

double prime_vertical_radius(double lat) { return kA / std::sqrt(1.0 - kE2 * std::sin(lat) * std::sin(lat)); }

std::string proj_message(PJ_CONTEXT* ctx) { return proj_context_errno_string(ctx, proj_context_errno(ctx)); }

}  // namespace

Geodetic parse_geodetic(const std::string& option, const std::string& text) {
  std::istringstream ss(text);
  Geodetic g;
  char c1 = 0, c2 = 0;
  std::string extra;
  if (!(ss >> g.lat_deg >> c1 >> g.lon_deg >> c2 >> g.alt_m) || c1 != ',' || c2 != ',' || (ss >> extra) ||
      !std::isfinite(g.lat_deg) || !std::isfinite(g.lon_deg) || !std::isfinite(g.alt_m))
    throw Error(option + ": expected \"LAT,LON,ALT\" (degrees, degrees, metres), got \"" + text + "\"");
  if (std::abs(g.lat_deg) > 90.0 || std::abs(g.lon_deg) > 180.0)
    throw Error(option + ": latitude must lie in [-90, 90] and longitude in [-180, 180], got \"" + text + "\"");
  return g;
}

Eigen::Vector3d ecef_from_geodetic(const Geodetic& g) {
  const double lat = g.lat_deg * kDeg, lon = g.lon_deg * kDeg, n = prime_vertical_radius(lat);
  return {(n + g.alt_m) * std::cos(lat) * std::cos(lon), (n + g.alt_m) * std::cos(lat) * std::sin(lon),
          (n * (1.0 - kE2) + g.alt_m) * std::sin(lat)};
}

Geodetic geodetic_from_ecef(const Eigen::Vector3d& p) {
  // Fixed-point iteration on the latitude: converges to well below a millimetre in a few steps
  // anywhere from the surface up to orbit.
  const double r = std::hypot(p.x(), p.y());
  double lat = std::atan2(p.z(), r * (1.0 - kE2)), h = 0.0;
  for (int k = 0; k < 8; ++k) {
    const double n = prime_vertical_radius(lat);
    h = std::abs(lat) < M_PI / 4 ? r / std::cos(lat) - n : p.z() / std::sin(lat) - n * (1.0 - kE2);
    lat = std::atan2(p.z(), r * (1.0 - kE2 * n / (n + h)));
  }
  return {lat / kDeg, std::atan2(p.y(), p.x()) / kDeg, h};
}

Eigen::Isometry3d T_ecef_enu(const Geodetic& origin) {
  const double lat = origin.lat_deg * kDeg, lon = origin.lon_deg * kDeg;
  Eigen::Matrix3d R;  // columns: east, north, up in ECEF
  R.col(0) << -std::sin(lon), std::cos(lon), 0.0;
  R.col(1) << -std::sin(lat) * std::cos(lon), -std::sin(lat) * std::sin(lon), std::cos(lat);
  R.col(2) << std::cos(lat) * std::cos(lon), std::cos(lat) * std::sin(lon), std::sin(lat);
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = R;
  T.translation() = ecef_from_geodetic(origin);
  return T;
}

int utm_epsg(const Geodetic& g) {
  int zone = static_cast<int>(std::floor((g.lon_deg + 180.0) / 6.0)) % 60 + 1;
  if (g.lat_deg >= 56.0 && g.lat_deg < 64.0 && g.lon_deg >= 3.0 && g.lon_deg < 12.0) zone = 32;  // south-west Norway
  if (g.lat_deg >= 72.0 && g.lat_deg < 84.0 && g.lon_deg >= 0.0 && g.lon_deg < 42.0)             // Svalbard
    zone = g.lon_deg < 9.0 ? 31 : g.lon_deg < 21.0 ? 33 : g.lon_deg < 33.0 ? 35 : 37;
  return (g.lat_deg >= 0.0 ? 32600 : 32700) + zone;
}

std::string utm_name(int epsg) { return std::to_string(epsg % 100) + (epsg / 100 == 326 ? "N" : "S"); }

int parse_crs(const std::string& text) {
  if (text == "utm" || text == "UTM") return 0;
  size_t used = 0;
  int code = 0;
  try {
    if (text.rfind("EPSG:", 0) == 0 || text.rfind("epsg:", 0) == 0) code = std::stoi(text.substr(5), &used);
  } catch (const std::exception&) {}
  if (code <= 0 || used != text.size() - 5) throw Error("--crs: expected EPSG:NNNN or utm, got \"" + text + "\"");
  return code;
}

struct CrsTransform::Impl {
  PJ_CONTEXT* ctx = proj_context_create();
  PJ* target = nullptr;  // the CRS as asked for (its WKT)
  PJ* pj = nullptr;      // geocentric -> target, GIS axis order
  std::mutex mutex;      // a PJ is not thread-safe
  ~Impl() {
    proj_destroy(pj);
    proj_destroy(target);
    proj_context_destroy(ctx);
  }
};

CrsTransform::CrsTransform(int epsg) : epsg_(epsg), impl_(std::make_unique<Impl>()) {
  PJ_CONTEXT* ctx = impl_->ctx;
  proj_log_level(ctx, PJ_LOG_NONE);  // failures become one Error, not PROJ's own lines on stderr
  const std::string code = "EPSG:" + std::to_string(epsg);
  impl_->target = proj_create(ctx, code.c_str());
  if (!impl_->target || !proj_is_crs(impl_->target))
    throw Error("--crs: PROJ does not know the CRS " + code + " (" + proj_message(ctx) + ")");
  // To a 2D CRS PROJ passes the ellipsoidal height through as z (checked by tests/test_geo.cpp).
  PJ* source = proj_create(ctx, "EPSG:4978");
  PJ* raw = proj_create_crs_to_crs_from_pj(ctx, source, impl_->target, nullptr, nullptr);
  proj_destroy(source);
  if (raw) impl_->pj = proj_normalize_for_visualization(ctx, raw);
  proj_destroy(raw);
  if (!impl_->pj) throw Error("--crs: PROJ has no transformation from WGS84 to " + code + " (" + proj_message(ctx) + ")");
}

CrsTransform::~CrsTransform() = default;

std::string CrsTransform::name() const {
  const char* n = proj_get_name(impl_->target);
  return n ? n : "EPSG:" + std::to_string(epsg_);
}

std::string CrsTransform::wkt() const {
  const char* options[] = {"MULTILINE=NO", nullptr};
  const char* w = proj_as_wkt(impl_->ctx, impl_->target, PJ_WKT1_GDAL, options);
  if (!w) throw Error("--crs: PROJ cannot write EPSG:" + std::to_string(epsg_) + " as WKT 1");
  return w;
}

void CrsTransform::from_ecef(std::vector<Eigen::Vector3d>& points) const {
  if (points.empty()) return;
  std::lock_guard lock(impl_->mutex);
  const size_t stride = sizeof(Eigen::Vector3d), n = points.size();
  double* p = points[0].data();
  proj_trans_generic(impl_->pj, PJ_FWD, p, stride, n, p + 1, stride, n, p + 2, stride, n, nullptr, 0, 0);
  for (const Eigen::Vector3d& q : points)
    if (!q.allFinite()) throw Error("--crs: a point lies outside the area where EPSG:" + std::to_string(epsg_) + " is defined");
}

Eigen::Vector3d CrsTransform::from_ecef(const Eigen::Vector3d& p) const {
  std::vector<Eigen::Vector3d> one{p};
  from_ecef(one);
  return one[0];
}

Geodetic CrsTransform::to_geodetic(const Eigen::Vector3d& p) const {
  PJ_COORD c = proj_coord(p.x(), p.y(), p.z(), 0.0);
  {
    std::lock_guard lock(impl_->mutex);
    c = proj_trans(impl_->pj, PJ_INV, c);
  }
  if (!std::isfinite(c.xyz.x))
    throw Error("--crs: a point lies outside the area where EPSG:" + std::to_string(epsg_) + " is defined");
  return geodetic_from_ecef(Eigen::Vector3d(c.xyz.x, c.xyz.y, c.xyz.z));
}

}  // namespace gcmap
