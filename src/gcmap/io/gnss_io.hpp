#pragma once
// GNSS fixes from gnss.txt: one fix a line, "stamp latitude longitude altitude sigma_east
// sigma_north sigma_up" (s; degrees WGS84; m above the ellipsoid; m, one standard deviation each),
// whitespace separated, stamps strictly increasing; '#' starts a comment line. A receiver's "no
// fix" epochs are simply absent. Also the trajectory outputs of a georeferenced run: UTM (TUM
// lines) and WGS84 (stamp lat lon alt and the orientation in the local ENU frame at each pose).
#include <Eigen/Geometry>
#include <string>
#include <vector>

#include "gcmap/io/bag_reader.hpp"
#include "gcmap/io/geo.hpp"

namespace gcmap {

struct GnssFix {
  double stamp = 0.0;
  Geodetic position;
  Eigen::Vector3d sigma_enu = Eigen::Vector3d::Ones();  // m: east, north, up
};

// Throws Error("PATH:LINE: ...") for a malformed line, a value out of range (latitude beyond +-90,
// longitude beyond +-180, a sigma not > 0), a stamp not after the line before, or a file without fixes.
std::vector<GnssFix> read_gnss_txt(const std::string& path);
// The same from text in memory; `name` stands for the file in errors.
std::vector<GnssFix> parse_gnss_txt(std::string_view text, const std::string& name);
// Full precision, with a header comment; written to a temporary name and renamed.
void write_gnss_txt(const std::string& path, const std::vector<GnssFix>& fixes);

// The fixes of a sensor_msgs/NavSatFix topic, by header stamp (stamps on the scans' clock).
struct GnssTopic {
  std::vector<GnssFix> fixes;
  size_t no_fix = 0;              // epochs skipped: status NO_FIX (or unknown), or a position that is not finite
  size_t unknown_covariance = 0;  // fixes given the fallback sigmas: covariance type unknown, or not positive
  size_t duplicates = 0;          // dropped for repeating the stamp before them
  // One line saying what was read, skipped and assumed, for the log and stats.json.
  std::string describe(const std::string& source, const Eigen::Vector3d& fallback_sigma) const;
};

// The topics of sensor_msgs/NavSatFix type.
std::vector<std::string> gnss_topics(const BagReader& bag);
// Sigmas (east, north, up) from the covariance's diagonal; `fallback_sigma` where the driver gave
// none. Throws Error naming the bag, topic and message for an undecodable message or a latitude or
// longitude out of range, and naming the topic when it is not NavSatFix or has no fix at all.
GnssTopic read_bag_gnss(BagReader& bag, const std::string& topic, const Eigen::Vector3d& fallback_sigma);

// A fix's position in the local ENU frame at `origin`.
Eigen::Vector3d enu_from_geodetic(const Geodetic& origin, const Geodetic& g);

// Poses of the local ENU frame at `origin` (x east, y north, z up) written as TUM lines in the UTM
// zone of the origin (`epsg` from utm_epsg): positions through PROJ, orientations turned by the
// grid convergence at each pose (the angle between grid north and true north), heights ellipsoidal.
void write_trajectory_utm(const std::string& path, const Geodetic& origin, int epsg, const std::vector<double>& stamps,
                          const std::vector<Eigen::Isometry3d>& T_enu_frame);
// "stamp lat lon alt qx qy qz qw": the orientation in the local ENU frame at the pose's own position.
void write_trajectory_wgs84(const std::string& path, const Geodetic& origin, const std::vector<double>& stamps,
                            const std::vector<Eigen::Isometry3d>& T_enu_frame);

// The rotation from the ENU frame at `origin` to the one at `g` (they differ by the curvature of
// the Earth: about 1.6e-4 rad per km).
Eigen::Matrix3d R_enu_at(const Geodetic& g, const Geodetic& origin);
// The rotation about up from the local ENU axes to the UTM grid axes at `g` (the grid convergence).
Eigen::Matrix3d R_grid_enu(const CrsTransform& utm, const Geodetic& g);

}  // namespace gcmap
