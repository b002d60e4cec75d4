#include "export_scans.hpp"

#include <spdlog/spdlog.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <filesystem>
#include <memory>

#include "gcmap/calibration/elevation_calibration.hpp"
#include "gcmap/core/error.hpp"
#include "gcmap/core/preprocess.hpp"
#include "gcmap/core/se3.hpp"
#include "gcmap/io/bag_reader.hpp"
#include "gcmap/io/bag_scans.hpp"
#include "gcmap/io/file.hpp"
#include "gcmap/io/sequence.hpp"
#include "gcmap/session/session.hpp"

namespace gcmap::cli {
namespace {

namespace fs = std::filesystem;

constexpr double kStampTolerance = 1e-4;  // s; scans are at least milliseconds apart
constexpr int kSweepSamples = 100;        // poses over a sweep: 1 ms steps for a 10 Hz sensor

// What OUT/stats.json says about the input of the run; empty strings where it says nothing.
struct RecordedInput {
  std::string input, topic, times_file;
};

RecordedInput read_recorded_input(const std::string& out) {
  const fs::path stats = fs::path(out) / "stats.json";
  if (!fs::exists(stats)) return {};
  YAML::Node root;
  try {
    root = YAML::Load(read_file(stats.string()));
  } catch (const YAML::Exception& e) { throw Error(stats.string() + ": not valid JSON (" + e.msg + ")"); }
  const YAML::Node a = root["assumptions"];
  if (!a || !a.IsMap()) return {};
  const auto text = [&](const char* key) { return a[key] && a[key].IsScalar() ? a[key].as<std::string>() : std::string(); };
  return {text("input"), text("topic"), text("times_file")};
}

std::unique_ptr<ScanSource> open_recording(const std::string& input, const RecordedInput& recorded) {
  if (is_bag_path(input)) {
    BagScanOptions bo;
    bo.topic = recorded.topic;
    return std::make_unique<BagScanRecords>(input, bo);
  }
  InputOptions io;
  if (!recorded.times_file.empty() && fs::exists(recorded.times_file)) io.times_file = recorded.times_file;
  return std::make_unique<FolderScanSource>(decide_input(input, io), 0, 0);
}

// T_map_sensor `dt` s after frame i's stamp: along the motion from frame i to the next (the last
// frame continues the motion before it).
Eigen::Isometry3d pose_at(const Trajectory& t, size_t i, double dt) {
  size_t a = i, b = i + 1;
  if (b >= t.size()) {
    if (i == 0) return t.poses[0];
    a = i - 1, b = i;
  }
  const double span = t.stamps[b] - t.stamps[a];
  if (!(span > 0.0)) return t.poses[i];
  const double u = (t.stamps[i] + dt - t.stamps[a]) / span;
  return t.poses[a] * se3_exp(u * se3_log(t.poses[a].inverse() * t.poses[b]));
}

void move_to_map(const Trajectory& t, MappedScan& s) {
  PointCloud& c = s.cloud;
  if (!c.has_times()) {
    const Eigen::Isometry3f T = t.poses[s.frame].cast<float>();
    for (Eigen::Vector3f& p : c.points) p = T * p;
    s.origins = {Eigen::Vector3f(T.translation())};
    s.origin_of.assign(c.size(), 0);
    return;
  }
  const auto [lo, hi] = std::minmax_element(c.times.begin(), c.times.end());
  const float t0 = *lo, step = std::max(*hi - *lo, 1e-6f) / (kSweepSamples - 1);
  std::vector<Eigen::Isometry3f> T(kSweepSamples);
  for (int k = 0; k < kSweepSamples; ++k) {
    T[k] = pose_at(t, s.frame, t0 + k * step).cast<float>();
    s.origins.push_back(T[k].translation());
  }
  s.origin_of.resize(c.size());
  for (size_t i = 0; i < c.size(); ++i) {
    const int k = std::clamp(static_cast<int>(std::lround((c.times[i] - t0) / step)), 0, kSweepSamples - 1);
    s.origin_of[i] = static_cast<uint16_t>(k);
    c.points[i] = T[k] * c.points[i];
  }
}

std::string stamp_text(double s) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.6f", s);
  return buf;
}

// The next scan of `source` at frame `frame`'s stamp, skipping scans before it (a run from --start).
ScanRecord scan_at(ScanSource& source, const std::string& input, const Trajectory& t, size_t frame) {
  const std::string hint = ": not the recording this map was made from? (give the right one with --scans)";
  for (;;) {
    std::optional<ScanRecord> r = source.next();
    if (!r)
      throw Error(input + ": ends before frame " + std::to_string(frame) + " (stamp " + stamp_text(t.stamps[frame]) + ")" + hint);
    if (r->stamp < t.stamps[frame] - kStampTolerance) continue;
    if (r->stamp > t.stamps[frame] + kStampTolerance)
      throw Error(input + ": no scan at frame " + std::to_string(frame) + "'s stamp " + stamp_text(t.stamps[frame]) +
                  " (the next is at " + stamp_text(r->stamp) + ")" + hint);
    return std::move(*r);
  }
}

}  // namespace

std::string recorded_input(const std::string& out, const std::string& given) {
  if (!given.empty()) {
    if (!fs::exists(given)) throw Error(given + ": --scans: no such file or folder");
    return given;
  }
  const std::string input = read_recorded_input(out).input;
  return !input.empty() && fs::exists(input) ? input : std::string();
}

void for_each_mapped_scan(const std::string& out, const std::string& input, const Trajectory& t,
                          const std::function<void(MappedScan&)>& visit, const std::function<void(size_t, size_t)>& progress) {
  if (t.stamps.size() != t.size()) throw Error(input + ": the trajectory has no stamps to match its scans by");
  const std::unique_ptr<ScanSource> source = open_recording(input, read_recorded_input(out));
  const size_t chunk = 4 * static_cast<size_t>(tbb::this_task_arena::max_concurrency());
  std::vector<std::pair<size_t, ScanRecord>> batch;
  for (size_t frame = 0; frame < t.size();) {
    batch.clear();
    for (; batch.size() < chunk && frame < t.size(); ++frame) batch.emplace_back(frame, scan_at(*source, input, t, frame));
    tbb::parallel_for(size_t{0}, batch.size(), [&](size_t k) {
      MappedScan s{batch[k].first, t.stamps[batch[k].first], batch[k].second.load(), {}, {}};
      move_to_map(t, s);
      visit(s);
    });
    progress(frame, t.size());
  }
}

namespace {

Eigen::AlignedBox2d reach_of(const std::vector<Eigen::Vector3f>& origins, float max_range) {
  Eigen::AlignedBox2d box;
  for (const Eigen::Vector3f& o : origins) box.extend(o.head<2>().cast<double>());
  const Eigen::Vector2d grow = Eigen::Vector2d::Constant(max_range + 1.0);
  return Eigen::AlignedBox2d(box.min() - grow, box.max() + grow);
}

RayBatch batch_of(const MappedScan& s) { return {s.cloud.points, s.origin_of, s.origins}; }

GridResult grid_from_scans(const std::string& out, const std::string& input, const GridOptions& o, const Eigen::Isometry3d& L,
                           const std::function<void(size_t, size_t)>& progress) {
  Trajectory t = read_trajectory((fs::path(out) / "trajectory.tum").string());
  for (Eigen::Isometry3d& T : t.poses) T = L * T;
  std::vector<Eigen::Vector3f> positions;
  for (const Eigen::Isometry3d& T : t.poses) positions.push_back(T.translation().cast<float>());
  OccupancyGridBuilder b(reach_of(positions, o.max_range), o);
  const size_t n = t.size();
  for_each_mapped_scan(
      out, input, t, [&](MappedScan& s) { b.add_ground(batch_of(s)); }, [&](size_t d, size_t) { progress(d, 2 * n); });
  b.finish_ground();
  for_each_mapped_scan(
      out, input, t, [&](MappedScan& s) { b.add_rays(batch_of(s)); }, [&](size_t d, size_t) { progress(n + d, 2 * n); });
  GridResult r;
  r.grid = b.grid();
  r.source = "rays: the " + std::to_string(n) + " scans of " + input +
             " in the final trajectory, each point cast from the sensor's position at its own time";
  return r;
}

struct SubmapRays {
  std::vector<Eigen::Vector3f> ends, origins;
  std::vector<uint16_t> origin_of;
};

// The submap's points in the map frame, each from its nearest keyframe (which saw it, most likely).
SubmapRays submap_rays(const Session& s, size_t k, const Eigen::Isometry3d& L) {
  SubmapRays r;
  const Submap& m = s.submaps[k];
  const Eigen::Isometry3f T = (L * s.T_world_submap[k]).cast<float>();
  for (const Eigen::Isometry3d& K : m.T_submap_keyframe)
    r.origins.push_back((L * s.T_world_submap[k] * K).translation().cast<float>());
  if (r.origins.empty()) return r;
  for (const Eigen::Vector3f& p : m.cloud->points) {
    const Eigen::Vector3f q = T * p;
    uint16_t best = 0;
    for (size_t j = 1; j < r.origins.size() && j < 65536; ++j)
      if ((r.origins[j] - q).squaredNorm() < (r.origins[best] - q).squaredNorm()) best = static_cast<uint16_t>(j);
    r.ends.push_back(q);
    r.origin_of.push_back(best);
  }
  return r;
}

GridResult grid_from_session(const std::string& out, const GridOptions& o, const Eigen::Isometry3d& L,
                             const std::function<void(size_t, size_t)>& progress) {
  const std::string dir = (fs::path(out) / "session").string();
  const Session s = read_session(dir);
  std::vector<SubmapRays> rays(s.submaps.size());
  tbb::parallel_for(size_t{0}, rays.size(), [&](size_t k) { rays[k] = submap_rays(s, k, L); });
  std::vector<Eigen::Vector3f> origins;
  for (const SubmapRays& r : rays) origins.insert(origins.end(), r.origins.begin(), r.origins.end());
  OccupancyGridBuilder b(reach_of(origins, o.max_range), o);
  const auto batch = [&](size_t k) { return RayBatch{rays[k].ends, rays[k].origin_of, rays[k].origins}; };
  tbb::parallel_for(size_t{0}, rays.size(), [&](size_t k) { b.add_ground(batch(k)); });
  b.finish_ground();
  progress(rays.size(), 2 * rays.size());
  tbb::parallel_for(size_t{0}, rays.size(), [&](size_t k) { b.add_rays(batch(k)); });
  progress(2 * rays.size(), 2 * rays.size());
  GridResult r;
  r.grid = b.grid();
  r.source = "rays: the submap clouds of " + dir +
             " (the scans are not on disk), each point cast from the nearest keyframe of its submap";
  return r;
}

// The walls of the session's submaps (0.5 m voxels: planes stay planes) stand the map upright.
Eigen::Matrix3d wall_levelling(const Session& s) {
  std::vector<CalibrationScan> clouds(s.submaps.size());
  tbb::parallel_for(size_t{0}, clouds.size(), [&](size_t k) {
    clouds[k].cloud = voxel_downsample(*s.submaps[k].cloud, 0.5);
    estimate_covariances(clouds[k].cloud);
    clouds[k].T_world_sensor = s.T_world_submap[k];
  });
  return levelling_rotation(clouds);
}

std::pair<Eigen::Matrix3d, std::string> grid_levelling(const std::string& out) {
  const fs::path session = fs::path(out) / "session";
  if (recorded_enu_origin(out)) return {Eigen::Matrix3d::Identity(), "none: the map frame is local ENU (GNSS)"};
  if (recorded_gravity_level(out)) return {Eigen::Matrix3d::Identity(), "none: the map frame is levelled by the IMU's gravity"};
  if (!fs::exists(session / "manifest.yaml")) return {Eigen::Matrix3d::Identity(), "none: no session/ to find walls in"};
  const Eigen::Matrix3d R = wall_levelling(read_session(session.string()));
  char text[160];
  std::snprintf(text, sizeof text, "the map frame turned by roll %.3f deg, pitch %.3f deg, so that its walls stand vertical",
                std::atan2(R(2, 1), R(2, 2)) * 180.0 / M_PI, std::asin(std::clamp(-R(2, 0), -1.0, 1.0)) * 180.0 / M_PI);
  return {R, text};
}

}  // namespace

namespace {
YAML::Node read_stats(const fs::path& stats) {
  try {
    return YAML::Load(read_file(stats.string()));
  } catch (const YAML::Exception& e) { throw Error(stats.string() + ": not valid JSON (" + e.msg + ")"); }
}
}  // namespace

bool recorded_gravity_level(const std::string& out) {
  const fs::path stats = fs::path(out) / "stats.json";
  if (!fs::exists(stats)) return false;
  const YAML::Node root = read_stats(stats);
  const YAML::Node imu = root["imu"];
  if (!imu || !imu.IsMap() || !imu["gravity"] || !imu["gravity"].IsMap()) return false;
  const YAML::Node level = imu["gravity"]["levelled"];
  return level && level.as<bool>(false);
}

std::optional<Geodetic> recorded_enu_origin(const std::string& out) {
  const fs::path stats = fs::path(out) / "stats.json";
  if (!fs::exists(stats)) return std::nullopt;
  const YAML::Node gnss = read_stats(stats)["gnss"];
  if (!gnss || !gnss["georeferenced"] || !gnss["georeferenced"].as<bool>(false)) return std::nullopt;
  const YAML::Node o = gnss["enu_origin"];
  if (!o || !o.IsSequence() || o.size() != 3) throw Error(stats.string() + ": gnss.enu_origin is not [lat, lon, alt]");
  return Geodetic{o[0].as<double>(), o[1].as<double>(), o[2].as<double>()};
}

GridResult make_grid(const std::string& out, const std::string& input, const GridOptions& options,
                     const std::function<void(size_t, size_t)>& progress) {
  if (input.empty() && !fs::exists(fs::path(out) / "session" / "manifest.yaml"))
    throw Error(out + ": neither the scans it was mapped from nor session/: nothing to cast rays from (give --scans)");
  const auto [R, levelling] = grid_levelling(out);
  Eigen::Isometry3d L = Eigen::Isometry3d::Identity();
  L.linear() = R;
  GridResult r = input.empty() ? grid_from_session(out, options, L, progress) : grid_from_scans(out, input, options, L, progress);
  r.R_level_map = R;
  r.levelling = levelling;
  return r;
}

}  // namespace gcmap::cli
