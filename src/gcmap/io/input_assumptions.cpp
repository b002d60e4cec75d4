#include "gcmap/io/input_assumptions.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "gcmap/core/error.hpp"
#include "gcmap/io/bag_scans.hpp"
#include "gcmap/io/file.hpp"
#include "gcmap/io/inspect.hpp"
#include "gcmap/io/sequence.hpp"

namespace gcmap {

namespace fs = std::filesystem;

const char* layout_name(InputLayout layout) {
  switch (layout) {
    case InputLayout::kitti: return "kitti";
    case InputLayout::folder: return "folder";
    case InputLayout::bag: return "bag";
  }
  return "?";
}

const char* stamp_source_name(StampSource source) {
  switch (source) {
    case StampSource::times_file: return "times_file";
    case StampSource::bag_header: return "bag_header";
    case StampSource::point_times: return "point_times";
    case StampSource::assumed_rate: return "assumed_rate";
  }
  return "?";
}

namespace {

// Absolute, normalized, without a trailing separator.
fs::path clean(const fs::path& p) {
  fs::path out = fs::absolute(p.empty() ? fs::path(".") : p).lexically_normal();
  return out.filename().empty() ? out.parent_path() : out;
}

bool present(const fs::path& p) {
  std::error_code ec;
  return fs::exists(p, ec);
}

// One stamp per line (KITTI's times.txt); Error naming the file and line for anything else.
std::vector<double> read_stamps(const std::string& path) {
  std::istringstream in(read_file(path));
  std::vector<double> stamps;
  std::string line;
  for (size_t n = 1; std::getline(in, line); ++n) {
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    std::istringstream ls(line);
    double t;
    std::string extra;
    if (!(ls >> t) || !std::isfinite(t) || (ls >> extra))
      throw Error(path + ": line " + std::to_string(n) + ": expected one stamp in seconds, got \"" + line + "\"");
    if (!stamps.empty() && t < stamps.back())
      throw Error(path + ": line " + std::to_string(n) + ": stamp " + std::to_string(t) + " s is before the previous " +
                  std::to_string(stamps.back()) + " s (stamps must not go backwards)");
    stamps.push_back(t);
  }
  return stamps;
}

// The stamps file: --times, else where the KITTI layout keeps it (the sequence folder beside
// velodyne/), inside the scans folder, beside the scans folder.
std::string find_times(const InputAssumptions& a, const InputOptions& o, std::vector<std::string>& looked) {
  if (!o.times_file.empty()) {
    if (!present(o.times_file)) throw Error(o.times_file + ": --times: no such file");
    return o.times_file;
  }
  std::vector<fs::path> candidates = {fs::path(a.root) / "times.txt", fs::path(a.scans_dir) / "times.txt",
                                      fs::path(a.scans_dir).parent_path() / "times.txt"};
  for (const fs::path& p : candidates) {
    const std::string s = clean(p).string();
    if (std::find(looked.begin(), looked.end(), s) != looked.end()) continue;
    looked.push_back(s);
    if (present(p)) return s;
  }
  return {};
}

void decide_stamps(InputAssumptions& a, const InputOptions& o) {
  std::vector<std::string> looked;
  a.times_path = find_times(a, o, looked);
  if (a.times_path.empty()) {
    a.stamp_source = StampSource::assumed_rate;
    for (size_t k = 0; k < a.files.size(); ++k) a.stamps.push_back(k / a.assumed_rate_hz);
    std::string where;
    for (const std::string& l : looked) where += (where.empty() ? "" : ", ") + l;
    a.stamps_text = {"assumed " + std::to_string(int(a.assumed_rate_hz)) + " Hz", "no times.txt (looked for " + where + ")"};
    a.warnings.push_back("no stamps: scans assumed " + std::to_string(1.0 / a.assumed_rate_hz).substr(0, 3) +
                         " s apart (no times.txt in " + where + "; name one with --times FILE)");
    return;
  }
  a.stamps = read_stamps(a.times_path);
  if (a.stamps.size() != a.files.size())
    throw Error(a.times_path + ": " + std::to_string(a.stamps.size()) + " stamps for " + std::to_string(a.files.size()) +
                " scans in " + a.scans_dir + " (one line per scan expected; name the right file with --times)");
  a.stamp_source = StampSource::times_file;
  a.stamps_text = {"times file", a.times_path + ", one stamp per scan"};
  size_t duplicates = 0;
  for (size_t k = 1; k < a.stamps.size(); ++k) duplicates += a.stamps[k] == a.stamps[k - 1];
  if (duplicates) a.warnings.push_back(a.times_path + ": " + std::to_string(duplicates) + " stamps equal to the previous one");
}

// KITTI's 0.22 deg correction only for KITTI's own recordings: every piece of evidence must hold.
void decide_kitti(InputAssumptions& a, const InputOptions& o, const ScanShape* shape) {
  std::string no;
  const bool all_bin =
      std::all_of(a.files.begin(), a.files.end(), [](const std::string& f) { return fs::path(f).extension() == ".bin"; });
  const bool calib = present(fs::path(a.root) / "calib.txt"), times = present(fs::path(a.root) / "times.txt");
  if (a.layout == InputLayout::bag) no = "a bag, not KITTI's .bin layout";
  else if (a.layout != InputLayout::kitti) no = "not the KITTI layout (no velodyne/ folder)";
  else if (!all_bin) no = "scans are not KITTI's .bin files";
  else if (!calib && !times) no = "no calib.txt or times.txt beside velodyne/";
  else if (present(fs::path(a.root) / "scenario.json")) no = "scenario.json: written by gcmap simulate";
  else if (!shape || shape->rings < 60 || shape->rings > 68)
    no = "the first scan shows " + (shape ? std::to_string(shape->rings) : std::string("no readable")) +
         " rings, not the HDL-64's 64";
  if (!no.empty()) {
    a.elevation_correction = {"none", no};
    return;
  }
  const std::string evidence = "KITTI layout, .bin scans, " + std::string(calib ? "calib.txt" : "times.txt") +
                               " beside velodyne/, " + std::to_string(shape->rings) + " rings (" + shape->ring_evidence + ")";
  a.kitti_correction = o.kitti_vertical_correction;
  a.elevation_correction = {
      o.kitti_vertical_correction ? "KITTI HDL-64 0.22 deg" : "none",
      o.kitti_vertical_correction ? evidence : evidence + ", but preprocess.kitti_vertical_correction is off"};
}

void decide_deskew(InputAssumptions& a, const InputOptions& o) {
  if (!o.deskew) a.deskew = {"off", "preprocess.deskew is off (--no-deskew)"};
  else if (a.point_times) a.deskew = {"on", "per-point times: " + a.point_times_text.value};
  else if (o.deskew_from_azimuth) a.deskew = {"on", "per-point times derived from the azimuth (preprocess.deskew_from_azimuth)"};
  else a.deskew = {"off", "the scans carry no per-point times"};
  if (!o.elevation_calibration.empty()) a.beam_calibration = {o.elevation_calibration, "preprocess.elevation_calibration"};
  else if (o.estimate_elevation_frames > 0)
    a.beam_calibration = {"estimated before mapping",
                          "calibration.estimate_elevation, from the odometry of the first " +
                              std::to_string(o.estimate_elevation_frames) + " frames"};
  else a.beam_calibration = {"none", "preprocess.elevation_calibration is empty, calibration.estimate_elevation is off"};
}

void check_first_times(InputAssumptions& a, const std::vector<float>& times, double offset, double interval) {
  const PointTimeCheck c = check_point_times(times, offset, interval);
  if (!c.mistake.empty()) a.warnings.push_back("first scan: " + c.message);
}

void decide_folder(InputAssumptions& a, const InputOptions& o) {
  const fs::path in = clean(a.input);
  // DIR/velodyne given itself: the sequence folder is its parent (unless it holds a velodyne/ of
  // its own: then it is the sequence folder, only named so).
  const bool inside_velodyne = in.filename() == "velodyne" && !is_kitti_layout(a.input);
  a.layout = is_kitti_layout(a.input) || inside_velodyne ? InputLayout::kitti : InputLayout::folder;
  a.root = (inside_velodyne ? in.parent_path() : in).string();
  a.files = list_scan_files(a.input);
  a.scans = a.files.size();
  a.scans_dir = clean(fs::path(a.files.front()).parent_path()).string();
  const std::string ext = fs::path(a.files.front()).extension().string();
  a.layout_text = {a.layout == InputLayout::kitti ? "KITTI sequence" : "folder of scans",
                   std::to_string(a.scans) + " " + ext + " scans in " + a.scans_dir};
  decide_stamps(a, o);
  const fs::path point_times = fs::path(a.root) / "point_times", labels = fs::path(a.root) / "labels";
  a.point_times = present(point_times);
  a.point_times_text =
      a.point_times ? Assumed{"seconds after the stamp (sweep start)", point_times.string() + "/NNNNNN.bin, float32 per point"}
                    : Assumed{"none", "no " + point_times.string() + "/"};
  a.labels = present(labels) ? Assumed{"SemanticKITTI", labels.string() + "/NNNNNN.label"}
                             : Assumed{"none", "no " + labels.string() + "/"};
  std::optional<ScanShape> shape;
  try {
    PointCloud first = read_point_cloud(a.files.front(), o.bin_fields);
    shape = scan_shape(first);
    const std::string sidecar = (point_times / (fs::path(a.files.front()).stem().string() + ".bin")).string();
    if (a.point_times && present(sidecar)) {
      const std::string bytes = read_file(sidecar);
      std::vector<float> t(bytes.size() / 4);
      if (!t.empty()) std::memcpy(t.data(), bytes.data(), t.size() * 4);
      check_first_times(a, t, 0.0, a.stamps.size() > 1 ? a.stamps[1] - a.stamps[0] : 0.1);
    }
  } catch (const Error& e) { a.warnings.push_back(std::string("first scan unreadable: ") + e.what()); }
  decide_kitti(a, o, shape ? &*shape : nullptr);
}

// Silences the log while a bag is looked at ahead: the run's own reader reports its damage once.
class QuietLog {
 public:
  QuietLog() : level_(spdlog::get_level()) { spdlog::set_level(spdlog::level::err); }
  ~QuietLog() { spdlog::set_level(level_); }

 private:
  spdlog::level::level_enum level_;
};

void decide_bag(InputAssumptions& a, const InputOptions& o) {
  a.layout = InputLayout::bag;
  const QuietLog quiet;
  BagScanSource source(a.input, BagScanOptions{.topic = o.topic});
  a.topic = source.topic();
  a.scans = source.message_count();
  const std::string field = describe_cloud_topic(const_cast<BagReader&>(source.bag()), a.topic).time_field;
  a.layout_text = {"ROS bag", std::to_string(a.scans) + " messages on " + a.topic + " of " + a.input};
  a.point_times = field != "none";
  a.point_times_text =
      a.point_times ? Assumed{field, "the point field of " + a.topic} : Assumed{"none", "no per-point time field on " + a.topic};
  a.stamp_source = a.point_times ? StampSource::point_times : StampSource::bag_header;
  a.stamps_text = a.point_times
                      ? Assumed{"earliest point time", "points carry " + field + "; times re-based to the earliest point"}
                      : Assumed{"header stamps", "no per-point times on " + a.topic};
  a.labels = {"none", "bags carry no labels"};
  BagScan first, second;
  if (a.point_times && source.next(first)) {
    const double interval = source.next(second) ? second.header_stamp - first.header_stamp : 0.1;
    check_first_times(a, first.cloud.times, first.stamp - first.header_stamp, interval);
  }
  decide_kitti(a, o, nullptr);
}

// Sigmas for a NavSatFix without a covariance: a single-point receiver's.
const Eigen::Vector3d kNavSatFallbackSigma(3.0, 3.0, 5.0);

void state_gnss(InputAssumptions& a, const std::string& evidence) {
  const GnssFix& first = a.gnss_fixes.front();
  char origin[128];
  std::snprintf(origin, sizeof(origin), "%.8f, %.8f, %.3f m", first.position.lat_deg, first.position.lon_deg,
                first.position.alt_m);
  a.gnss = {std::to_string(a.gnss_fixes.size()) + " fixes, stamps on the scans' clock, heights ellipsoidal; map frame: local " +
                "ENU (x east, y north, z up) at the first fix (" + origin +
                ") once the fixes span gnss.align_distance (yaw fitted; the first scan taken as level until the fixes " +
                "correct roll and pitch)",
            evidence};
}

void read_gnss_topic(InputAssumptions& a, BagReader& bag, const std::string& topic, const std::string& how) {
  const GnssTopic t = read_bag_gnss(bag, topic, kNavSatFallbackSigma);
  a.gnss_fixes = t.fixes;
  a.gnss_path = bag.path() + ": topic " + topic;
  state_gnss(a, t.describe(a.gnss_path, kNavSatFallbackSigma) + ", " + how);
  if (t.unknown_covariance > 0)
    a.warnings.push_back(topic + ": " + std::to_string(t.unknown_covariance) +
                         " fixes carry no covariance; their sigmas are assumed (see the gnss line)");
}

// A bag's NavSatFix topic: --gnss-topic, else its only one.
bool decide_bag_gnss(InputAssumptions& a, const InputOptions& o) {
  const QuietLog quiet;
  const std::unique_ptr<BagReader> bag = open_bag(a.input);
  if (!o.gnss_topic.empty()) {
    read_gnss_topic(a, *bag, o.gnss_topic, "--gnss-topic");
    return true;
  }
  const std::vector<std::string> topics = gnss_topics(*bag);
  if (topics.size() == 1) read_gnss_topic(a, *bag, topics.front(), "the bag's only sensor_msgs/NavSatFix topic");
  if (topics.size() > 1) {
    std::string names;
    for (const std::string& t : topics) names += (names.empty() ? "" : ", ") + t;
    a.gnss = {"none", "the bag has " + std::to_string(topics.size()) + " NavSatFix topics (" + names +
                          "): choose one with --gnss-topic"};
    a.warnings.push_back("GNSS not used: " + a.gnss.evidence);
  }
  return !topics.empty();
}

// --gnss, else --gnss-topic, else gnss.txt beside the scans as times.txt is (bags: beside the bag),
// else a bag's only NavSatFix topic.
void decide_gnss(InputAssumptions& a, const InputOptions& o) {
  const bool bag = a.layout == InputLayout::bag;
  if (!o.gnss_topic.empty() && (!bag || !o.gnss_file.empty()))
    throw Error("--gnss-topic: " + std::string(bag ? "give --gnss or --gnss-topic, not both" : "the input is not a bag"));
  if (!o.gnss_topic.empty()) {
    decide_bag_gnss(a, o);
    return;
  }
  std::vector<fs::path> candidates;
  if (!o.gnss_file.empty()) {
    if (!present(o.gnss_file)) throw Error(o.gnss_file + ": --gnss: no such file");
    a.gnss_path = o.gnss_file;
  } else if (bag) {
    candidates = {clean(a.input).parent_path() / "gnss.txt"};
  } else {
    candidates = {fs::path(a.root) / "gnss.txt", fs::path(a.scans_dir) / "gnss.txt",
                  fs::path(a.scans_dir).parent_path() / "gnss.txt"};
  }
  for (const fs::path& p : candidates)
    if (a.gnss_path.empty() && present(p)) a.gnss_path = clean(p).string();
  if (a.gnss_path.empty()) {
    if (bag && decide_bag_gnss(a, o)) return;
    a.gnss = {"none", bag ? "no NavSatFix topic in the bag, no gnss.txt beside it and no --gnss"
                          : "no gnss.txt beside the scans and no --gnss"};
    return;
  }
  a.gnss_fixes = read_gnss_txt(a.gnss_path);
  state_gnss(a, a.gnss_path + (o.gnss_file.empty() ? ", found beside the scans" : ", --gnss"));
}

// What the run does with an IMU: the gyro deskews (when deskewing is on), the LiDAR-inertial state
// predicts the sweeps (imu.inertial_odometry), the accelerometer levels the map (imu.level_map).
std::string imu_use(bool deskewing, const InputOptions& o) {
  const std::string gyro = deskewing ? "gyro deskews each sweep (its bias estimated from the registration)"
                                     : "gyro does not deskew (deskewing is off)";
  const std::string inertial = o.imu_inertial_odometry
                                   ? "pose, velocity and biases from the IMU and the registration predict each sweep and give "
                                     "its pose, also where the registration cannot see or place it (imu.inertial_odometry)"
                                   : "no LiDAR-inertial state (imu.inertial_odometry off): the gyro predicts the rotation"
                                     " only";
  const std::string accel = o.imu_levels_map ? "accelerometer levels the map (gravity in the global graph, its bias estimated)"
                                             : "accelerometer does not level the map (imu.level_map off)";
  if (!deskewing && !o.imu_levels_map && !o.imu_inertial_odometry)
    return "read, not used: deskewing is off and so are imu.level_map and imu.inertial_odometry";
  return gyro + "; " + inertial + "; " + accel;
}

void take_imu(InputAssumptions& a, ImuStream stream, const std::string& path, const std::string& how, const InputOptions& o) {
  a.imu_path = path;
  a.imu = {imu_use(a.deskew.value == "on", o), stream.describe(path) + ", " + how};
  if (!a.stamps.empty() && (stream.samples.back().stamp < a.stamps.front() || stream.samples.front().stamp > a.stamps.back()))
    throw Error(path + ": the IMU stamps (" + std::to_string(stream.samples.front().stamp) + " to " +
                std::to_string(stream.samples.back().stamp) + " s) do not overlap the scans' (" + std::to_string(a.stamps.front()) +
                " to " + std::to_string(a.stamps.back()) + " s): another clock? (imu.time_offset, --no-imu)");
  a.imu_samples = std::move(stream.samples);
}

// A bag's IMU topic: --imu-topic, else its only one; several: an Error listing them.
void decide_bag_imu(InputAssumptions& a, const InputOptions& o) {
  const QuietLog quiet;
  const std::unique_ptr<BagReader> bag = open_bag(a.input);
  std::string topic = o.imu_topic, how = "--imu-topic";
  if (topic.empty()) {
    const std::vector<std::string> topics = imu_topics(*bag);
    if (topics.empty()) return;
    if (topics.size() > 1) {
      std::string names;
      for (const std::string& t : topics) names += (names.empty() ? "" : ", ") + t;
      throw Error(a.input + ": " + std::to_string(topics.size()) + " sensor_msgs/Imu topics (" + names +
                  "): choose one with --imu-topic, or --no-imu");
    }
    topic = topics.front(), how = "the bag's only sensor_msgs/Imu topic";
  }
  take_imu(a, read_bag_imu(*bag, topic), bag->path() + ": topic " + topic, how, o);
}

// --no-imu: none; --imu, else --imu-topic, else imu.txt beside the scans as times.txt is (bags:
// beside the bag), else a bag's only IMU topic.
void decide_imu(InputAssumptions& a, const InputOptions& o) {
  const bool bag = a.layout == InputLayout::bag;
  if (!o.imu_topic.empty() && (!bag || !o.imu_file.empty()))
    throw Error("--imu-topic: " + std::string(bag ? "give --imu or --imu-topic, not both" : "the input is not a bag"));
  a.imu = {"none", bag ? "no sensor_msgs/Imu topic in the bag, no imu.txt beside it and no --imu"
                       : "no imu.txt beside the scans and no --imu"};
  if (!o.use_imu) {
    a.imu = {"none", "imu.use is off (--no-imu)"};
    return;
  }
  if (!o.imu_file.empty() && !present(o.imu_file)) throw Error(o.imu_file + ": --imu: no such file");
  std::vector<fs::path> candidates;
  if (!o.imu_file.empty()) candidates = {o.imu_file};
  else if (bag && o.imu_topic.empty()) candidates = {clean(a.input).parent_path() / "imu.txt"};
  else if (!bag) candidates = {fs::path(a.root) / "imu.txt", fs::path(a.scans_dir) / "imu.txt", fs::path(a.scans_dir).parent_path() / "imu.txt"};
  for (const fs::path& p : candidates) {
    if (!present(p)) continue;
    const std::string path = clean(p).string();
    take_imu(a, read_imu_txt(path), path, o.imu_file.empty() ? "found beside the scans" : "--imu", o);
    return;
  }
  if (bag) decide_bag_imu(a, o);
}

}  // namespace

InputAssumptions decide_input(const std::string& input, const InputOptions& options) {
  InputAssumptions a;
  a.input = input;
  if (is_bag_path(input)) decide_bag(a, options);
  else decide_folder(a, options);
  decide_deskew(a, options);
  decide_gnss(a, options);
  decide_imu(a, options);
  return a;
}

std::vector<std::string> InputAssumptions::lines() const {
  std::vector<std::string> out;
  auto add = [&](const char* what, const Assumed& x) {
    out.push_back(std::string(what) + ": " + x.value + " (" + x.evidence + ")");
  };
  add("layout", layout_text);
  add("stamps", stamps_text);
  add("per-point times", point_times_text);
  add("deskewing", deskew);
  add("elevation correction", elevation_correction);
  add("beam calibration", beam_calibration);
  add("labels", labels);
  add("gnss", gnss);
  add("imu", imu);
  for (const std::string& w : warnings) out.push_back("warning: " + w);
  return out;
}

Json InputAssumptions::to_json() const {
  Json j = Json::object();
  auto add = [&](const char* key, const Assumed& x) {
    Json e = Json::object();
    e["value"] = x.value;
    e["evidence"] = x.evidence;
    j[key] = e;
  };
  j["input"] = input;
  j["layout_kind"] = layout_name(layout);
  j["scans"] = scans;
  if (layout == InputLayout::bag) j["topic"] = topic;  // export re-reads the scans from it
  j["stamp_source"] = stamp_source_name(stamp_source);
  if (!times_path.empty()) j["times_file"] = times_path;
  if (stamp_source == StampSource::assumed_rate) j["assumed_rate_hz"] = assumed_rate_hz;
  j["kitti_elevation_correction"] = kitti_correction;
  add("layout", layout_text);
  add("stamps", stamps_text);
  add("point_times", point_times_text);
  add("deskewing", deskew);
  add("elevation_correction", elevation_correction);
  add("beam_calibration", beam_calibration);
  add("labels", labels);
  add("gnss", gnss);
  if (!gnss_path.empty()) j["gnss_file"] = gnss_path;
  add("imu", imu);
  if (!imu_path.empty()) j["imu_file"] = imu_path;
  Json w = Json::array();
  for (const std::string& s : warnings) w.push_back(s);
  j["warnings"] = w;
  return j;
}

}  // namespace gcmap
