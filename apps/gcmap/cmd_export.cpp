// gcmap export: the map of a gcmap map output folder as LAS 1.4, PLY or PCD, georeferenced when
// the geodetic origin of the map frame is given.
#include <spdlog/spdlog.h>

#include <cstdio>
#include <filesystem>
#include <optional>
#include <regex>

#include "commands.hpp"
#include "gcmap/core/error.hpp"
#include "gcmap/core/se3.hpp"
#include "gcmap/io/file.hpp"
#include "gcmap/io/geo.hpp"
#include "gcmap/io/las.hpp"
#include "gcmap/io/point_cloud_io.hpp"
#include "gcmap/io/trajectory_io.hpp"
#include "gcmap/mapping/mapper.hpp"
#include "gcmap/session/session.hpp"
#include "progress.hpp"

namespace gcmap::cli {
namespace {

namespace fs = std::filesystem;

enum class ExportFormat { las, ply, pcd };
enum class MapSource { automatic, session, map_ply };

struct ExportOptions {
  std::string input, output, format = "las", origin, crs, from = "auto", intensity = "auto";
  size_t max_points = 20'000'000;
  bool quiet = false;
};

// The map in the map frame, with the submap of each point when it came from the session.
struct ExportMap {
  MapSource source = MapSource::session;
  std::string path;
  PointCloud cloud;
  std::vector<uint16_t> source_ids;
  size_t submaps = 0;
};

ExportFormat parse_format(const std::string& s) {
  if (s == "las") return ExportFormat::las;
  if (s == "ply") return ExportFormat::ply;
  if (s == "pcd") return ExportFormat::pcd;
  throw Error("--format: expected las, ply or pcd, got \"" + s + "\"");
}

MapSource parse_source(const std::string& s) {
  if (s == "auto") return MapSource::automatic;
  if (s == "session") return MapSource::session;
  if (s == "map") return MapSource::map_ply;
  throw Error("--from: expected auto, session or map, got \"" + s + "\"");
}

ExportMap load_session(const std::string& dir) {
  const Session s = read_session(dir);
  if (s.submaps.size() > 65536)
    throw Error(dir + ": " + std::to_string(s.submaps.size()) + " submaps do not fit LAS's 16-bit point source id");
  ExportMap m{MapSource::session, dir, {}, {}, s.submaps.size()};
  const bool intensities = have_intensities(s.submaps);
  for (size_t k = 0; k < s.submaps.size(); ++k) {
    const PointCloud& c = *s.submaps[k].cloud;
    const Eigen::Isometry3f T = s.T_world_submap[k].cast<float>();
    for (const Eigen::Vector3f& p : c.points) m.cloud.points.push_back(T * p);
    if (intensities) m.cloud.intensities.insert(m.cloud.intensities.end(), c.intensities.begin(), c.intensities.end());
    m.source_ids.resize(m.cloud.size(), static_cast<uint16_t>(k));
  }
  return m;
}

ExportMap load_map(const std::string& out, MapSource from) {
  const fs::path session = fs::path(out) / "session", ply = fs::path(out) / "map.ply";
  if (from == MapSource::automatic) from = fs::exists(session / "manifest.yaml") ? MapSource::session : MapSource::map_ply;
  if (from == MapSource::session) return load_session(fs::exists(session) ? session.string() : out);
  if (!fs::exists(ply)) throw Error(out + ": neither session/ nor map.ply: not an output folder of gcmap map");
  return {MapSource::map_ply, ply.string(), read_point_cloud(ply.string()), {}, 0};
}

// The UTM zone of the trajectory files: the --crs one when it is a WGS84 / UTM code.
int trajectory_utm_epsg(int crs, const Geodetic& origin) {
  const bool utm = (crs > 32600 && crs <= 32660) || (crs > 32700 && crs <= 32760);
  return utm ? crs : utm_epsg(origin);
}

struct Georeference {
  Geodetic origin;
  Eigen::Isometry3d T_ecef_map;
  std::unique_ptr<CrsTransform> crs;  // of the points; null: local ENU
  std::unique_ptr<CrsTransform> utm;  // of the trajectory files
};

std::optional<Georeference> make_georeference(const ExportOptions& o) {
  if (o.origin.empty()) {
    if (!o.crs.empty()) throw Error("--crs: needs --origin (the geodetic origin of the map frame)");
    return std::nullopt;
  }
  Georeference g;
  g.origin = parse_geodetic("--origin", o.origin);
  g.T_ecef_map = T_ecef_enu(g.origin);
  int code = o.crs.empty() ? -1 : parse_crs(o.crs);
  if (code == 0) code = utm_epsg(g.origin);
  if (code > 0) g.crs = std::make_unique<CrsTransform>(code);
  g.utm = std::make_unique<CrsTransform>(trajectory_utm_epsg(code, g.origin));
  return g;
}

std::vector<std::string> assumptions(const ExportOptions& o, const ExportMap& m, const std::optional<Georeference>& g,
                                     IntensityScaling scaling) {
  std::vector<std::string> a;
  a.push_back(m.source == MapSource::session ? "points: every submap cloud of " + m.path +
                                                   " in the optimized frame (overlaps kept; point source id = submap index)"
                                             : "points: " + m.path + " (point source id 0)");
  if (!g) a.push_back("coordinates: the map frame (frame 0's sensor frame), no CRS");
  else if (!g->crs) a.push_back("coordinates: local ENU at the origin (map frame axes taken as east, north, up), no CRS");
  else
    a.push_back("coordinates: " + g->crs->name() + " (EPSG:" + std::to_string(g->crs->epsg()) +
                "), heights above the WGS84 ellipsoid");
  if (g)
    a.push_back("origin: map frame origin at " + o.origin +
                " (lat, lon in degrees, metres above the WGS84 ellipsoid), axes east, north, up");
  if (parse_format(o.format) != ExportFormat::las) return a;
  if (!m.cloud.has_intensities()) a.push_back("intensity: none in the source, written as 0");
  else
    a.push_back(scaling == IntensityScaling::unit ? "intensity: values in [0, 1] scaled by 65535"
                                                  : "intensity: raw values rounded, clamped to [0, 65535]");
  a.push_back("gps time: 0 (map points are merged from many scans: no single scan stamp)");
  a.push_back("classification: 0, never classified (no labels in the map)");
  return a;
}

IntensityScaling intensity_scaling(const ExportOptions& o, const PointCloud& cloud) {
  return o.intensity == "auto" ? detect_intensity_scaling(cloud.intensities) : parse_intensity_scaling(o.intensity);
}

LasCloud georeferenced_las(const ExportMap& m, const std::optional<Georeference>& g, IntensityScaling scaling) {
  LasCloud las = las_cloud(m.cloud, Eigen::Isometry3d::Identity(), scaling, 0, 0.0);
  if (!m.source_ids.empty()) las.point_source_ids = m.source_ids;
  if (!g || !g->crs) return las;
  for (Eigen::Vector3d& p : las.points) p = g->T_ecef_map * p;
  g->crs->from_ecef(las.points);
  return las;
}

std::vector<std::string> write_map(const ExportOptions& o, const ExportMap& m, const std::optional<Georeference>& g,
                                   IntensityScaling scaling, const std::string& staging) {
  const ExportFormat format = parse_format(o.format);
  if (format == ExportFormat::ply) write_ply((fs::path(staging) / "map.ply").string(), m.cloud);
  if (format == ExportFormat::pcd) write_pcd((fs::path(staging) / "map.pcd").string(), m.cloud);
  if (format != ExportFormat::las) return {o.format == "ply" ? "map.ply" : "map.pcd"};
  const LasCloud las = georeferenced_las(m, g, scaling);
  LasWriteOptions w;
  if (g && g->crs) w.wkt = g->crs->wkt();
  std::vector<std::string> names;
  for (const std::string& p : write_las_tiles(staging, "map", las, o.max_points, w))
    names.push_back(fs::path(p).filename().string());
  return names;
}

// Stale tiles of an earlier, larger export would read as part of this map.
void remove_stale_tiles(const std::string& dir, const std::vector<std::string>& written) {
  static const std::regex tile(R"(map(_\d{3,})?\.las)");
  for (const auto& e : fs::directory_iterator(dir)) {
    const std::string name = e.path().filename().string();
    if (std::regex_match(name, tile) && std::find(written.begin(), written.end(), name) == written.end()) fs::remove(e.path());
  }
}

struct GeoPose {
  Eigen::Vector3d position;  // in the file's coordinates
  Eigen::Quaterniond q;      // sensor orientation in the file's axes
};

// A map-frame pose in UTM (orientation in grid axes) and in WGS84 (orientation in the local ENU).
std::pair<GeoPose, GeoPose> geo_poses(const Georeference& g, const Eigen::Isometry3d& T_map_sensor) {
  const Eigen::Vector3d e = g.T_ecef_map * T_map_sensor.translation();
  const Geodetic here = geodetic_from_ecef(e);
  const Eigen::Matrix3d R_ecef_local = T_ecef_enu(here).linear();
  const Eigen::Matrix3d R_local_sensor = R_ecef_local.transpose() * g.T_ecef_map.linear() * T_map_sensor.linear();
  const Eigen::Vector3d p_utm = g.utm->from_ecef(e);
  const Eigen::Vector3d east = g.utm->from_ecef(e + R_ecef_local.col(0)) - p_utm;  // grid convergence
  const Eigen::Matrix3d R_grid_sensor =
      Eigen::AngleAxisd(std::atan2(east.y(), east.x()), Eigen::Vector3d::UnitZ()) * R_local_sensor;
  return {{p_utm, Eigen::Quaterniond(R_grid_sensor).normalized()},
          {{here.lat_deg, here.lon_deg, here.alt_m}, Eigen::Quaterniond(R_local_sensor).normalized()}};
}

std::string tum_line(double stamp, const Eigen::Vector3d& p, const Eigen::Quaterniond& q, const char* position_format) {
  char buf[256];
  const std::string f =
      std::string("%.9f ") + position_format + " " + position_format + " " + position_format + " %.9f %.9f %.9f %.9f\n";
  std::snprintf(buf, sizeof buf, f.c_str(), stamp, p.x(), p.y(), p.z(), q.x(), q.y(), q.z(), q.w());
  return buf;
}

std::string kitti_line(const Eigen::Vector3d& p, const Eigen::Quaterniond& q) {
  const Eigen::Matrix3d R = q.toRotationMatrix();
  char buf[320];
  std::snprintf(buf, sizeof buf, "%.9f %.9f %.9f %.4f %.9f %.9f %.9f %.4f %.9f %.9f %.9f %.4f\n", R(0, 0), R(0, 1), R(0, 2),
                p.x(), R(1, 0), R(1, 1), R(1, 2), p.y(), R(2, 0), R(2, 1), R(2, 2), p.z());
  return buf;
}

std::vector<std::string> write_trajectories(const Trajectory& t, const Georeference& g, const std::string& staging) {
  std::string enu = "# stamp x y z qx qy qz qw: local ENU at the origin (the map frame)\n";
  std::string utm_tum = "# stamp easting northing height qx qy qz qw: " + g.utm->name() + ", orientation in grid axes\n";
  std::string utm_kitti, wgs84 =
                             "# stamp latitude longitude altitude qx qy qz qw: degrees, metres above the WGS84 ellipsoid; "
                             "orientation in the local east-north-up frame at the position\n";
  for (size_t i = 0; i < t.size(); ++i) {
    const double stamp = i < t.stamps.size() ? t.stamps[i] : 0.0;
    const auto [utm, geo] = geo_poses(g, t.poses[i]);
    enu += tum_line(stamp, t.poses[i].translation(), Eigen::Quaterniond(t.poses[i].linear()).normalized(), "%.4f");
    utm_tum += tum_line(stamp, utm.position, utm.q, "%.4f");
    utm_kitti += kitti_line(utm.position, utm.q);
    wgs84 += tum_line(stamp, geo.position, geo.q, "%.10f");
  }
  const std::string zone = "trajectory_utm" + utm_name(g.utm->epsg());
  const std::vector<std::pair<std::string, const std::string*>> files = {
      {"trajectory_enu.tum", &enu}, {zone + ".tum", &utm_tum}, {zone + ".kitti", &utm_kitti}, {"trajectory_wgs84.txt", &wgs84}};
  std::vector<std::string> names;
  for (const auto& [name, text] : files) {
    write_file_atomic((fs::path(staging) / name).string(), [&](std::ostream& s) { s << *text; });
    names.push_back(name);
  }
  return names;
}

Json export_json(const ExportOptions& o, const ExportMap& m, const std::optional<Georeference>& g,
                 const std::vector<std::string>& assumed, const std::vector<std::string>& files) {
  Json j = Json::object();
  j["input"] = o.input;
  j["source"] = m.path;
  j["format"] = o.format;
  j["points"] = m.cloud.size();
  if (m.source == MapSource::session) j["submaps"] = m.submaps;
  if (g) j["origin"] = Json(Json::Array{g->origin.lat_deg, g->origin.lon_deg, g->origin.alt_m});
  if (g && g->crs) j["crs"] = "EPSG:" + std::to_string(g->crs->epsg());
  if (g) j["trajectory_crs"] = "EPSG:" + std::to_string(g->utm->epsg());
  Json a = Json::array(), f = Json::array();
  for (const std::string& s : assumed) a.push_back(s);
  for (const std::string& s : files) f.push_back(s);
  j["assumptions"] = a;
  j["files"] = f;
  return j;
}

int run_export(const ExportOptions& o) {
  const ExportFormat format = parse_format(o.format);
  const MapSource from = parse_source(o.from);
  const std::optional<Georeference> g = make_georeference(o);
  if (g && g->crs && format != ExportFormat::las)
    throw Error("--crs: needs --format las (PLY and PCD hold float32 coordinates: steps of 0.5 m at UTM northings)");
  if (!fs::is_directory(o.input)) throw Error(o.input + ": not a folder (give the output folder of gcmap map)");
  const ExportMap m = load_map(o.input, from);
  const IntensityScaling scaling = intensity_scaling(o, m.cloud);
  const std::vector<std::string> assumed = assumptions(o, m, g, scaling);
  for (const std::string& line : assumed) spdlog::info("{}", line);
  const fs::path tum = fs::path(o.input) / "trajectory.tum";
  if (g && !fs::exists(tum)) spdlog::warn("{}: absent, no georeferenced trajectories written", tum.string());
  std::error_code ec;
  fs::create_directories(o.output, ec);
  if (ec) throw Error(o.output + ": cannot create the output folder (" + ec.message() + ")");
  std::vector<std::string> files;
  Progress progress("export: writing", 0, o.quiet);
  write_folder_contents_atomic(o.output, [&](const std::string& staging) {
    files = write_map(o, m, g, scaling, staging);
    progress.update(m.cloud.size(), "points");
    if (g && fs::exists(tum))
      for (const std::string& name : write_trajectories(read_trajectory(tum.string()), *g, staging)) files.push_back(name);
    files.push_back("export.json");
    const Json j = export_json(o, m, g, assumed, files);
    write_file_atomic((fs::path(staging) / "export.json").string(), [&](std::ostream& s) { s << j.dump() << "\n"; });
  });
  progress.finish();
  if (format == ExportFormat::las) remove_stale_tiles(o.output, files);
  std::string list;
  for (const std::string& f : files) list += (list.empty() ? "" : ", ") + f;
  std::fprintf(stderr, "Exported %zu points in %.1f s. Wrote %s: %s.\n", m.cloud.size(), progress.seconds(), o.output.c_str(),
               list.c_str());
  return 0;
}

}  // namespace

void add_export(CLI::App& app, Runner& run) {
  auto o = std::make_shared<ExportOptions>();
  auto* cmd = app.add_subcommand("export",
                                 "Export the map of a gcmap map run as LAS 1.4, PLY or PCD, georeferenced when given an origin");
  cmd->add_option("OUT", o->input, "The output folder of gcmap map")->required();
  cmd->add_option("-o,--output", o->output, "Folder for the exported files")->required();
  cmd->add_option("--format", o->format, "las, ply or pcd")->capture_default_str();
  cmd->add_option("--origin", o->origin,
                  "LAT,LON,ALT: WGS84 position of the map frame's origin, its axes taken as east, north, up");
  cmd->add_option("--crs", o->crs, "EPSG:NNNN or utm (the origin's zone): coordinates of the LAS points (needs --origin)");
  cmd->add_option("--from", o->from, "auto (session/ when present, else map.ply), session or map")->capture_default_str();
  cmd->add_option("--intensity", o->intensity, "auto, unit (x 65535) or raw (rounded): float intensity to LAS's uint16")
      ->capture_default_str();
  cmd->add_option("--max-points", o->max_points, "Points per LAS file: larger maps are tiled as map_000.las, map_001.las, ...")
      ->capture_default_str();
  cmd->add_flag("--quiet", o->quiet, "No progress");
  cmd->callback([o, &run] { run = [o] { return run_export(*o); }; });
}

}  // namespace gcmap::cli
