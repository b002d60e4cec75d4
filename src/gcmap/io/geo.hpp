#pragma once
// Georeferencing: WGS84 geodetic <-> ECEF <-> local ENU at a geodetic origin (closed form), and
// WGS84 or ECEF -> any CRS by EPSG code through PROJ (UTM with the zone chosen automatically).
#include <Eigen/Geometry>
#include <memory>
#include <string>
#include <vector>

namespace gcmap {

struct Geodetic {
  double lat_deg = 0.0, lon_deg = 0.0, alt_m = 0.0;  // WGS84, altitude above the ellipsoid
};

// "LAT,LON,ALT" (degrees, degrees, metres); throws Error naming `option`.
Geodetic parse_geodetic(const std::string& option, const std::string& text);

Eigen::Vector3d ecef_from_geodetic(const Geodetic& g);
Geodetic geodetic_from_ecef(const Eigen::Vector3d& p_ecef);
// The local ENU frame (x east, y north, z up) at `origin`, as a pose in ECEF.
Eigen::Isometry3d T_ecef_enu(const Geodetic& origin);

// The UTM zone of a point (Norway's and Svalbard's exceptions included), as its WGS84 / UTM EPSG
// code: 326zz north of the equator, 327zz south.
int utm_epsg(const Geodetic& g);
std::string utm_name(int epsg);  // "32N" for 32632

// "EPSG:NNNN" -> NNNN; "utm" -> 0 (the origin's zone, decided by the caller). Throws Error.
int parse_crs(const std::string& text);

// A coordinate transformation from WGS84 geocentric (ECEF, EPSG:4978) to EPSG:`epsg`, axes in
// GIS order (easting or longitude first), heights ellipsoidal where the CRS has none of its own.
class CrsTransform {
 public:
  explicit CrsTransform(int epsg);  // throws Error when PROJ does not know the code
  ~CrsTransform();
  CrsTransform(const CrsTransform&) = delete;
  CrsTransform& operator=(const CrsTransform&) = delete;

  int epsg() const { return epsg_; }
  std::string name() const;  // e.g. "WGS 84 / UTM zone 32N"
  std::string wkt() const;   // OGC WKT 1 (GDAL flavour), as LAS 1.4 asks
  // In place, many points at once (thread-safe: each call uses its own PROJ context).
  void from_ecef(std::vector<Eigen::Vector3d>& points) const;
  Eigen::Vector3d from_ecef(const Eigen::Vector3d& p) const;
  Eigen::Vector3d from_geodetic(const Geodetic& g) const { return from_ecef(ecef_from_geodetic(g)); }
  Geodetic to_geodetic(const Eigen::Vector3d& p) const;  // the inverse, through ECEF

 private:
  struct Impl;
  int epsg_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace gcmap
