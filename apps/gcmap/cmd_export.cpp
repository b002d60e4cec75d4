// gcmap export: the map of a gcmap map output folder as LAS 1.4, PLY or PCD, georeferenced when
// the geodetic origin of the map frame is given.
#include <spdlog/spdlog.h>

#include <atomic>
#include <cstdio>
#include <filesystem>
#include <optional>
#include <regex>

#include "commands.hpp"
#include "export_scans.hpp"
#include "gcmap/core/error.hpp"
#include "gcmap/core/se3.hpp"
#include "gcmap/io/file.hpp"
#include "gcmap/io/geo.hpp"
#include "gcmap/io/las.hpp"
#include "gcmap/io/occupancy_grid_io.hpp"
#include "gcmap/io/point_cloud_io.hpp"
#include "gcmap/io/trajectory_io.hpp"
#include "gcmap/mapping/mapper.hpp"
#include "gcmap/session/session.hpp"
#include "gcmap/viz/render.hpp"
#include "progress.hpp"

namespace gcmap::cli {
namespace {

namespace fs = std::filesystem;

enum class ExportFormat { las, ply, pcd };
enum class MapSource { automatic, session, map_ply };
// What is exported: the map's points, a navigation grid, or every scan on its own.
enum class ExportKind { map, grid, per_scan };

struct ExportOptions {
  std::string input, output, format = "las", origin, crs, from = "auto", intensity = "auto";
  std::string color;  // empty: no colour (LAS format 6); height, intensity or submap: format 7
  size_t max_points = 20'000'000;
  bool quiet = false;
  bool grid = false, per_scan = false;
  std::string scans;                    // the recording, when it moved since the run
  double grid_resolution = 0.05;        // m
  std::string grid_height = "0.3,2.0";  // m above the local ground
  float grid_max_range = 40.f;          // m
};

ExportKind export_kind(const ExportOptions& o) {
  if (o.grid && o.per_scan) throw Error("--grid and --per-scan: one export at a time");
  if ((o.grid || o.per_scan) && !o.color.empty()) throw Error("--color: for the map's export, not --grid or --per-scan");
  return o.grid ? ExportKind::grid : o.per_scan ? ExportKind::per_scan : ExportKind::map;
}

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
  std::string origin_source;  // in words: --origin, or the run's GNSS
  Eigen::Isometry3d T_ecef_map;
  std::unique_ptr<CrsTransform> crs;  // of the points; null: local ENU
  std::unique_ptr<CrsTransform> utm;  // of the trajectory files
};

// --origin, else the run's own GNSS origin; none: the map frame, unreferenced.
std::optional<Georeference> make_georeference(const ExportOptions& o) {
  const std::optional<Geodetic> recorded = o.origin.empty() ? recorded_enu_origin(o.input) : std::nullopt;
  if (o.origin.empty() && !recorded) {
    if (!o.crs.empty()) throw Error("--crs: needs --origin (the geodetic origin of the map frame)");
    return std::nullopt;
  }
  Georeference g;
  g.origin = recorded ? *recorded : parse_geodetic("--origin", o.origin);
  g.origin_source = recorded ? "the run's GNSS (stats.json gnss.enu_origin)" : "--origin";
  g.T_ecef_map = T_ecef_enu(g.origin);
  int code = o.crs.empty() ? -1 : parse_crs(o.crs);
  if (code == 0) code = utm_epsg(g.origin);
  if (code > 0) g.crs = std::make_unique<CrsTransform>(code);
  g.utm = std::make_unique<CrsTransform>(trajectory_utm_epsg(code, g.origin));
  return g;
}

std::string origin_line(const Georeference& g) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "%.9f, %.9f, %.3f", g.origin.lat_deg, g.origin.lon_deg, g.origin.alt_m);
  return "origin: map frame origin at " + std::string(buf) + " from " + g.origin_source +
         " (lat, lon in degrees, metres above the WGS84 ellipsoid), axes east, north, up";
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
  if (g) a.push_back(origin_line(*g));
  if (parse_format(o.format) != ExportFormat::las) return a;
  if (!m.cloud.has_intensities()) a.push_back("intensity: none in the source, written as 0");
  else
    a.push_back(scaling == IntensityScaling::unit ? "intensity: values in [0, 1] scaled by 65535"
                                                  : "intensity: raw values rounded, clamped to [0, 65535]");
  a.push_back("gps time: 0 (map points are merged from many scans: no single scan stamp)");
  a.push_back(o.color.empty() ? "colour: none (point format 6)"
                              : "colour: by " + o.color + " (" +
                                    (o.color == "submap" ? "one colour per submap" : "the 2-98 % range on a blue-to-red scale") +
                                    "), point format 7");
  a.push_back("classification: 0, never classified (no labels in the map)");
  return a;
}

IntensityScaling intensity_scaling(const ExportOptions& o, const PointCloud& cloud) {
  return o.intensity == "auto" ? detect_intensity_scaling(cloud.intensities) : parse_intensity_scaling(o.intensity);
}

// Map-frame points into the CRS of the export (none: left in the map frame).
void georeference(LasCloud& las, const std::optional<Georeference>& g) {
  if (!g || !g->crs) return;
  for (Eigen::Vector3d& p : las.points) p = g->T_ecef_map * p;
  g->crs->from_ecef(las.points);
}

LasCloud georeferenced_las(const ExportOptions& o, const ExportMap& m, const std::optional<Georeference>& g,
                           IntensityScaling scaling) {
  LasCloud las = las_cloud(m.cloud, Eigen::Isometry3d::Identity(), scaling, 0, 0.0);
  if (!m.source_ids.empty()) las.point_source_ids = m.source_ids;
  if (!o.color.empty())
    for (const viz::Rgb& c : viz::point_colours(m.cloud, viz::parse_color_mode(o.color), m.source_ids))
      las.colors.push_back({uint16_t(c.r * 257), uint16_t(c.g * 257), uint16_t(c.b * 257)});
  georeference(las, g);
  return las;
}

std::vector<std::string> write_map(const ExportOptions& o, const ExportMap& m, const std::optional<Georeference>& g,
                                   IntensityScaling scaling, const std::string& staging) {
  const ExportFormat format = parse_format(o.format);
  if (format == ExportFormat::ply) write_ply((fs::path(staging) / "map.ply").string(), m.cloud);
  if (format == ExportFormat::pcd) write_pcd((fs::path(staging) / "map.pcd").string(), m.cloud);
  if (format != ExportFormat::las) return {o.format == "ply" ? "map.ply" : "map.pcd"};
  const LasCloud las = georeferenced_las(o, m, g, scaling);
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

// --grid-height "MIN,MAX" in metres above the local ground.
GridOptions grid_options(const ExportOptions& o) {
  GridOptions g;
  g.resolution = o.grid_resolution;
  g.max_range = o.grid_max_range;
  char tail = 0;
  if (std::sscanf(o.grid_height.c_str(), "%f,%f%c", &g.height_min, &g.height_max, &tail) != 2)
    throw Error("--grid-height: expected MIN,MAX in metres above the ground, got \"" + o.grid_height + "\"");
  if (!(g.height_min < g.height_max)) throw Error("--grid-height: MIN must be below MAX, got \"" + o.grid_height + "\"");
  if (!(g.resolution > 0.0) || !(g.resolution <= 10.0)) throw Error("--grid-resolution: expected (0, 10] m");
  if (!(g.max_range > g.min_range)) throw Error("--grid-max-range: must exceed 1 m");
  return g;
}

void write_json(const std::string& path, const Json& j) {
  write_file_atomic(path, [&](std::ostream& s) { s << j.dump() << "\n"; });
}

std::string joined(const std::vector<std::string>& names) {
  std::string list;
  for (const std::string& f : names) list += (list.empty() ? "" : ", ") + f;
  return list;
}

Json grid_json(const ExportOptions& o, const GridOptions& g, const GridResult& r) {
  Json j = Json::object();
  j["input"] = o.input;
  j["source"] = r.source;
  j["resolution"] = g.resolution;
  j["height_band"] = Json(Json::Array{g.height_min, g.height_max});
  j["height_reference"] = "the local ground: the lowest return within about 1.5 m that two more of its scan confirm";
  j["levelling"] = r.levelling;
  Json R = Json::array();
  for (int i = 0; i < 3; ++i)
    for (int k = 0; k < 3; ++k) R.push_back(r.R_level_map(i, k));
  j["R_level_map"] = R;
  j["frame"] = "the map frame turned by R_level_map (row major) about its origin; origin and cells in that frame";
  j["max_range"] = g.max_range;
  j["size"] = Json(Json::Array{r.grid.width, r.grid.height});
  j["origin"] = Json(Json::Array{r.grid.origin.x(), r.grid.origin.y(), 0.0});
  j["occupied_cells"] = r.grid.count(Occupancy::occupied);
  j["free_cells"] = r.grid.count(Occupancy::free);
  j["unknown_cells"] = r.grid.count(Occupancy::unknown);
  j["files"] = Json(Json::Array{"map.pgm", "map.yaml", "export.json"});
  return j;
}

int run_grid(const ExportOptions& o) {
  if (!o.origin.empty() || !o.crs.empty()) throw Error("--grid: the grid is in the map frame; --origin and --crs are for points");
  const GridOptions g = grid_options(o);
  if (!fs::is_directory(o.input)) throw Error(o.input + ": not a folder (give the output folder of gcmap map)");
  const std::string input = recorded_input(o.input, o.scans);
  if (input.empty()) spdlog::warn("{}: the scans it was mapped from are not on disk: rays from the session's submaps", o.input);
  Progress progress("export: occupancy grid (two passes)", 0, o.quiet);
  const GridResult r = make_grid(o.input, input, g,
                                 [&](size_t done, size_t total) { progress.update(done, "(of " + std::to_string(total) + ")"); });
  progress.finish();
  if (!o.quiet) spdlog::info("{}; levelling: {}", r.source, r.levelling);
  if (r.grid.cells.empty()) throw Error(o.input + ": no return fell in the grid's range and height band; nothing written");
  std::error_code ec;
  fs::create_directories(o.output, ec);
  if (ec) throw Error(o.output + ": cannot create the output folder (" + ec.message() + ")");
  write_folder_contents_atomic(o.output, [&](const std::string& staging) {
    write_map_server(staging, "map", r.grid);
    write_json((fs::path(staging) / "export.json").string(), grid_json(o, g, r));
  });
  std::fprintf(stderr,
               "Made a %d x %d occupancy grid at %.3f m (%zu occupied, %zu free cells) in %.1f s. Wrote %s: map.pgm, map.yaml, "
               "export.json.\n",
               r.grid.width, r.grid.height, g.resolution, r.grid.count(Occupancy::occupied), r.grid.count(Occupancy::free),
               progress.seconds(), o.output.c_str());
  return 0;
}

std::vector<std::string> per_scan_assumptions(const ExportOptions& o, const std::string& input,
                                              const std::optional<Georeference>& g) {
  std::vector<std::string> a;
  a.push_back("points: every scan of " + input +
              " as recorded (no filtering or elevation correction), moved into the map frame by the final trajectory, each "
              "point by the pose at its own time when the scan has per-point times (interpolated to the next frame)");
  a.push_back("files: scans/NNNNNN with NNNNNN the frame index (the line of trajectory.tum); poses.tum: each scan's pose");
  if (!g) a.push_back("coordinates: the map frame (frame 0's sensor frame), no CRS");
  else if (!g->crs) a.push_back("coordinates: local ENU at the origin (map frame axes taken as east, north, up), no CRS");
  else a.push_back("coordinates: " + g->crs->name() + " (EPSG:" + std::to_string(g->crs->epsg()) + ")");
  if (g) a.push_back(origin_line(*g));
  if (parse_format(o.format) == ExportFormat::las) {
    a.push_back("point source id: the frame index; gps time: the scan's stamp plus the point's time (the input's clock)");
    a.push_back(o.intensity == "auto" ? "intensity: unit or raw scaling decided per scan (values all in [0, 1]: unit)"
                                      : "intensity: " + o.intensity + " scaling");
  } else {
    a.push_back("fields: x y z, intensity and time (s after the scan's stamp) where the scan has them");
  }
  return a;
}

std::string scan_name(size_t frame, ExportFormat f) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "scans/%06zu.%s", frame,
                f == ExportFormat::las   ? "las"
                : f == ExportFormat::ply ? "ply"
                                         : "pcd");
  return buf;
}

void write_scan(const ExportOptions& o, const MappedScan& s, const std::optional<Georeference>& g, const std::string& staging) {
  const ExportFormat f = parse_format(o.format);
  const std::string path = (fs::path(staging) / scan_name(s.frame, f)).string();
  if (f == ExportFormat::ply) return write_ply(path, s.cloud);
  if (f == ExportFormat::pcd) return write_pcd(path, s.cloud);
  const IntensityScaling scaling = intensity_scaling(o, s.cloud);
  LasCloud las = las_cloud(s.cloud, Eigen::Isometry3d::Identity(), scaling, static_cast<uint16_t>(s.frame), s.stamp);
  georeference(las, g);
  LasWriteOptions w;
  if (g && g->crs) w.wkt = g->crs->wkt();
  write_las(path, las, w);
}

std::vector<std::string> write_scans(const ExportOptions& o, const std::string& input, const Trajectory& t,
                                     const std::optional<Georeference>& g, const std::string& staging) {
  fs::create_directories(fs::path(staging) / "scans");
  Progress progress("export: scans", t.size(), o.quiet);
  std::atomic<size_t> points{0};
  for_each_mapped_scan(
      o.input, input, t,
      [&](MappedScan& s) {
        write_scan(o, s, g, staging);
        points += s.cloud.size();
      },
      [&](size_t done, size_t) { progress.update(done, std::to_string(points.load()) + " points"); });
  progress.finish();
  Trajectory poses = t;
  poses.format = TrajectoryFormat::tum;
  write_trajectory((fs::path(staging) / "poses.tum").string(), poses);
  std::vector<std::string> files = {"scans/ (" + std::to_string(t.size()) + " files)", "poses.tum"};
  if (g)
    for (const std::string& name : write_trajectories(t, *g, staging)) files.push_back(name);
  return files;
}

Json per_scan_json(const ExportOptions& o, const std::string& input, const std::optional<Georeference>& g,
                   const std::vector<std::string>& assumed, size_t frames) {
  Json j = Json::object();
  j["input"] = o.input;
  j["source"] = input;
  j["format"] = o.format;
  j["scans"] = frames;
  if (g) j["origin"] = Json(Json::Array{g->origin.lat_deg, g->origin.lon_deg, g->origin.alt_m});
  if (g && g->crs) j["crs"] = "EPSG:" + std::to_string(g->crs->epsg());
  Json a = Json::array();
  for (const std::string& line : assumed) a.push_back(line);
  j["assumptions"] = a;
  return j;
}

int run_per_scan(const ExportOptions& o) {
  const ExportFormat format = parse_format(o.format);
  const std::optional<Georeference> g = make_georeference(o);
  if (g && g->crs && format != ExportFormat::las)
    throw Error("--crs: needs --format las (PLY and PCD hold float32 coordinates: steps of 0.5 m at UTM northings)");
  if (!fs::is_directory(o.input)) throw Error(o.input + ": not a folder (give the output folder of gcmap map)");
  const std::string input = recorded_input(o.input, o.scans);
  if (input.empty())
    throw Error(o.input + ": the scans it was mapped from are not on disk (see stats.json); give them with --scans");
  const Trajectory t = read_trajectory((fs::path(o.input) / "trajectory.tum").string());
  if (format == ExportFormat::las && t.size() > 65536)
    throw Error(o.input + ": " + std::to_string(t.size()) + " frames do not fit LAS's 16-bit point source id");
  const std::vector<std::string> assumed = per_scan_assumptions(o, input, g);
  for (const std::string& line : assumed) spdlog::info("{}", line);
  std::error_code ec;
  fs::create_directories(o.output, ec);
  if (ec) throw Error(o.output + ": cannot create the output folder (" + ec.message() + ")");
  std::vector<std::string> files;
  Stopwatch clock;
  write_folder_contents_atomic(o.output, [&](const std::string& staging) {
    files = write_scans(o, input, t, g, staging);
    files.push_back("export.json");
    write_json((fs::path(staging) / "export.json").string(), per_scan_json(o, input, g, assumed, t.size()));
  });
  std::fprintf(stderr, "Exported %zu scans in %.1f s. Wrote %s: %s.\n", t.size(), clock.ms() / 1e3, o.output.c_str(),
               joined(files).c_str());
  return 0;
}

int run_export(const ExportOptions& o) {
  const ExportKind kind = export_kind(o);
  if (kind == ExportKind::grid) return run_grid(o);
  if (kind == ExportKind::per_scan) return run_per_scan(o);
  const ExportFormat format = parse_format(o.format);
  const MapSource from = parse_source(o.from);
  const std::optional<Georeference> g = make_georeference(o);
  if (g && g->crs && format != ExportFormat::las)
    throw Error("--crs: needs --format las (PLY and PCD hold float32 coordinates: steps of 0.5 m at UTM northings)");
  if (!fs::is_directory(o.input)) throw Error(o.input + ": not a folder (give the output folder of gcmap map)");
  if (!o.color.empty()) {
    if (format != ExportFormat::las) throw Error("--color: LAS only (point format 7)");
    viz::parse_color_mode(o.color);
  }
  const ExportMap m = load_map(o.input, from);
  if (o.color == "submap" && m.source_ids.empty()) throw Error("--color submap: " + m.path + " has no submaps (use the session)");
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
                  "LAT,LON,ALT: WGS84 position of the map frame's origin, its axes taken as east, north, up (default: the "
                  "origin of a run that GNSS georeferenced, from its stats.json)");
  cmd->add_option("--crs", o->crs, "EPSG:NNNN or utm (the origin's zone): coordinates of the LAS points (needs --origin)");
  cmd->add_option("--from", o->from, "auto (session/ when present, else map.ply), session or map")->capture_default_str();
  cmd->add_option("--intensity", o->intensity, "auto, unit (x 65535) or raw (rounded): float intensity to LAS's uint16")
      ->capture_default_str();
  cmd->add_option("--color", o->color,
                  "height, intensity or submap: a colour per point for viewers that show RGB (LAS point format 7)");
  cmd->add_option("--max-points", o->max_points, "Points per LAS file: larger maps are tiled as map_000.las, map_001.las, ...")
      ->capture_default_str();
  cmd->add_flag("--grid", o->grid,
                "An occupancy grid for Nav2 / ROS map_server instead (map.pgm, map.yaml), made by casting every scan's rays");
  cmd->add_option("--grid-resolution", o->grid_resolution, "Grid cell size in m")->capture_default_str();
  cmd->add_option("--grid-height", o->grid_height, "MIN,MAX: the obstacle band in m above the local ground")
      ->capture_default_str();
  cmd->add_option("--grid-max-range", o->grid_max_range, "Returns farther than this (m, in the plane) are not used for the grid")
      ->capture_default_str();
  cmd->add_flag("--per-scan", o->per_scan,
                "Every scan on its own in the map frame instead (scans/NNNNNN.las|ply|pcd, poses.tum), with intensity and time");
  cmd->add_option("--scans", o->scans, "The recording the map was made from, when it is no longer where stats.json says");
  cmd->add_flag("--quiet", o->quiet, "No progress");
  cmd->callback([o, &run] { run = [o] { return run_export(*o); }; });
}

}  // namespace gcmap::cli
