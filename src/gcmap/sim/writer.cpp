// write_simulation: a simulated sequence on disk in the KITTI layout or as a ROS bag.
#include "gcmap/sim/writer.hpp"

#include <spdlog/spdlog.h>
#include <tbb/parallel_for.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>

#include "gcmap/core/error.hpp"
#include "gcmap/core/timer.hpp"
#include "gcmap/io/file.hpp"
#include "gcmap/io/imu_io.hpp"
#include "gcmap/io/json.hpp"
#include "gcmap/io/trajectory_io.hpp"

namespace gcmap::sim {

namespace {

namespace fs = std::filesystem;

template <typename T>
void write_binary(const fs::path& path, const std::vector<T>& data) {
  write_file_atomic(path.string(), [&](std::ostream& out) {
    out.write(reinterpret_cast<const char*>(data.data()), static_cast<std::streamsize>(data.size() * sizeof(T)));
  });
}

// k / 10 rounded once, as times.txt reads back and as a bag's ns stamp divided by 1e9 does.
double frame_stamp(size_t k) { return static_cast<double>(k) / 10.0; }

void write_labels(const fs::path& dir, size_t k, const PointCloud& c) {
  char name[32];
  std::snprintf(name, sizeof(name), "%06zu.label", k);
  if (c.has_labels()) write_binary(dir / "labels" / name, c.labels);
}

void write_kitti_scan(const fs::path& dir, size_t k, const PointCloud& c) {
  char name[32];
  std::vector<float> buf(c.size() * 4);
  for (size_t i = 0; i < c.size(); ++i) {
    buf[4 * i + 0] = c.points[i].x();
    buf[4 * i + 1] = c.points[i].y();
    buf[4 * i + 2] = c.points[i].z();
    buf[4 * i + 3] = c.intensities[i];
  }
  std::snprintf(name, sizeof(name), "%06zu.bin", k);
  write_binary(dir / "velodyne" / name, buf);
  if (c.has_times()) write_binary(dir / "point_times" / name, c.times);  // float32, s after the stamp
  write_labels(dir, k, c);
}

// The ideal scenarios spread their route over the frames asked for: few frames make a fast,
// violently accelerating drive, which the IMU then shows exactly.
void warn_unrealistic(const std::vector<ImuSample>& samples, const Simulator& sim) {
  double worst = 0.0;
  for (const ImuSample& s : samples) worst = std::max(worst, std::abs(s.accel.norm() - kStandardGravity));
  if (worst > kStandardGravity)
    spdlog::warn(
        "the simulated IMU feels up to {:.0f} m/s^2 besides gravity: the '{}' scenario drives its {:.0f} m "
        "in {} frames; give more --frames or a realistic scenario (city, highway, forest)",
        worst, sim.scenario().name, sim.path_length(), sim.num_frames());
}

// The cloud's times and its stamp as a recording with the mistake would hold them.
double apply_mistake(PointCloud& c, double stamp, TimeMistake m) {
  for (float& t : c.times) {
    if (m == TimeMistake::milliseconds) t *= 1e3f;
    if (m == TimeMistake::nanoseconds) t *= 1e9f;
    if (m == TimeMistake::absolute) t += static_cast<float>(1000.0 + stamp);  // a clock started 1000 s before the drive
    if (m == TimeMistake::sweep_end) t -= 0.1f;
    if (m == TimeMistake::zero) t = 0.f;
  }
  return m == TimeMistake::sweep_end ? stamp + 0.1 : stamp;
}

void check_mistake(const Simulator& sim, const OutputOptions& out) {
  if (out.mistake == TimeMistake::none) return;
  if (!sim.realism().motion_distortion) throw Error("--time-mistake needs per-point times: the realism key motion_distortion");
  const bool float_time = !out.bag || (out.message == ScanMessage::pointcloud2 && out.time == PointTimeConvention::velodyne_time);
  if (out.mistake != TimeMistake::zero && !float_time)
    throw Error("--time-mistake: other than zero, it needs a float time: the KITTI layout or --time-field velodyne");
}

NavSatFixMsg navsatfix(const GnssFix& f, GnssQuality quality) {
  NavSatFixMsg m;
  m.stamp_ns = std::llround(f.stamp * 1e9);
  m.status = quality == GnssQuality::single_point ? NavSatStatus::fix : NavSatStatus::gbas_fix;
  m.latitude = f.position.lat_deg;
  m.longitude = f.position.lon_deg;
  m.altitude = f.position.alt_m;
  for (int a = 0; a < 3; ++a) m.position_covariance[4 * a] = f.sigma_enu[a] * f.sigma_enu[a];
  m.covariance_type = NavSatCovariance::diagonal_known;
  return m;
}

// Where the frames go: the KITTI layout, or the bag with the labels beside it.
class FrameSink {
 public:
  FrameSink(const fs::path& dir, const Simulator& sim, const OutputOptions& out) : dir_(dir), mistake_(out.mistake) {
    check_mistake(sim, out);
    if (out.message == ScanMessage::livox_custom_msg && !out.bag)
      throw Error(dir.string() + ": Livox CustomMsg scans need a bag (mcap, db3 or ROS 1), not the KITTI layout");
    std::error_code ec;
    fs::create_directories(dir, ec);
    if (!ec && !out.bag) fs::create_directories(dir / "velodyne", ec);
    if (!ec && !out.bag && sim.realism().motion_distortion) fs::create_directories(dir / "point_times", ec);
    if (!ec && sim.realism().labels) fs::create_directories(dir / "labels", ec);
    if (ec) throw Error(dir.string() + ": cannot create output folder (" + ec.message() + ")");
    if (!out.bag) return;
    CloudLayout layout;
    layout.time = sim.realism().motion_distortion ? out.time : PointTimeConvention::none;
    if (out.message == ScanMessage::livox_custom_msg) {
      layout.time = PointTimeConvention::livox_custom_msg;  // offset_time 0 without motion distortion
      layout.reflectivity_scale = 255;                      // the simulator's intensities are in [0, 1]
    }
    BagWriterOptions wo;
    wo.compression = out.compression;
    bag_.emplace(simulated_bag_path(dir.string(), *out.bag), *out.bag, layout, wo);
  }
  void write(size_t k, const PointCloud& c) {
    if (mistake_ != TimeMistake::none) return write_with_mistake(k, c);
    if (!bag_) return write_kitti_scan(dir_, k, c);
    bag_->write(c, frame_stamp(k));
    write_labels(dir_, k, c);
  }
  // The /imu topic, recorded at each sample's stamp.
  void write_imu(const std::vector<ImuSample>& samples, bool in_g) {
    if (!bag_) return;
    const uint32_t topic = bag_->writer().add_topic("/imu", "sensor_msgs/msg/Imu");
    ImuMsg m;
    m.frame_id = "imu";
    for (const ImuSample& s : samples) {
      m.stamp_ns = std::llround(s.stamp * 1e9);
      const Eigen::Vector3d a = in_g ? Eigen::Vector3d(s.accel / kStandardGravity) : s.accel;
      m.angular_velocity = {s.gyro.x(), s.gyro.y(), s.gyro.z()};
      m.linear_acceleration = {a.x(), a.y(), a.z()};
      bag_->writer().write(topic, m.stamp_ns, encode_imu(m, bag_->encoding()));
    }
  }
  // The /gnss topic (sensor_msgs/NavSatFix) as a driver publishes it: NO_FIX epochs included.
  void write_gnss(const SimulatedGnss& gnss, GnssQuality quality) {
    if (!bag_) return;
    const uint32_t topic = bag_->writer().add_topic("/gnss", "sensor_msgs/msg/NavSatFix");
    std::vector<NavSatFixMsg> messages;
    for (const GnssFix& f : gnss.fixes) messages.push_back(navsatfix(f, quality));
    for (double t : gnss.no_fix_stamps) {
      NavSatFixMsg m;
      m.stamp_ns = std::llround(t * 1e9);
      m.status = NavSatStatus::no_fix;
      m.latitude = m.longitude = m.altitude = std::numeric_limits<double>::quiet_NaN();
      messages.push_back(m);
    }
    std::sort(messages.begin(), messages.end(), [](const auto& a, const auto& b) { return a.stamp_ns < b.stamp_ns; });
    for (NavSatFixMsg& m : messages) {
      m.frame_id = "gnss";
      bag_->writer().write(topic, m.stamp_ns, encode_navsatfix(m, bag_->encoding()));
    }
  }
  void write_with_mistake(size_t k, PointCloud c) {
    const double stamp = apply_mistake(c, frame_stamp(k), mistake_);
    if (!bag_) return write_kitti_scan(dir_, k, c);
    bag_->write(c, stamp);
    write_labels(dir_, k, c);
  }
  void close() {
    if (bag_) bag_->close();
  }

 private:
  fs::path dir_;
  TimeMistake mistake_;
  std::optional<ScanBagWriter> bag_;
};

const char* time_field_note(PointTimeConvention t) {
  switch (t) {
    case PointTimeConvention::ouster_t: return "t: uint32 ns after the header stamp (Ouster)";
    case PointTimeConvention::velodyne_time: return "time: float32 s after the header stamp (Velodyne)";
    case PointTimeConvention::hesai_timestamp: return "timestamp: float64 s, absolute (Hesai)";
    case PointTimeConvention::livox_offset_time: return "offset_time: uint32 ns after the header stamp (Livox)";
    default: return "none";
  }
}

Json imu_json(const ImuSimConfig& c, const OutputOptions& out) {
  Json j = Json::object();
  j["file"] = "imu.txt: stamp gx gy gz (rad/s) ax ay az (m/s^2), IMU frame; imu_bias.txt: the true biases at each stamp";
  if (out.bag)
    j["topic"] = std::string("/imu: sensor_msgs/Imu, header stamps as in imu.txt, acceleration in ") +
                 (out.message == ScanMessage::livox_custom_msg ? "g (Livox driver)" : "m/s^2");
  j["rate_hz"] = c.rate;
  j["gravity"] = "9.80665 m/s^2 along -z of the world (poses_world.txt)";
  j["trajectory"] =
      "smooth through the IMU poses at the frame stamps: quintic Hermite positions, cubic Hermite rotation "
      "increments; exact derivatives of it";
  Json T = Json::array();
  const Eigen::Matrix<double, 3, 4> m = c.T_lidar_imu.matrix().topRows<3>();
  for (int r = 0; r < 3; ++r)
    for (int k = 0; k < 4; ++k) T.push_back(m(r, k));
  j["T_lidar_imu"] = T;
  j["T_lidar_imu_layout"] = "3x4 row-major [R t]: a point in the IMU frame to the LiDAR frame";
  j["time_offset_s"] = c.time_offset;
  j["time_offset"] = "imu stamp = true time + time_offset_s";
  j["noise"] = c.noise;
  j["gyro_noise_density"] = c.noise ? c.density.gyro_noise : 0.0;
  j["accel_noise_density"] = c.noise ? c.density.accel_noise : 0.0;
  j["gyro_bias_random_walk"] = c.noise ? c.density.gyro_bias_walk : 0.0;
  j["accel_bias_random_walk"] = c.noise ? c.density.accel_bias_walk : 0.0;
  j["noise_units"] =
      "rad/s/sqrt(Hz), m/s^2/sqrt(Hz), rad/s^2/sqrt(Hz), m/s^3/sqrt(Hz); initial biases N(0, 0.002 rad/s), N(0, 0.05 m/s^2)";
  return j;
}

Json gnss_json(const GnssSimConfig& c, const SimulatedGnss& g, bool bag) {
  const GnssNoise n = gnss_noise(c.quality);
  Json j = Json::object();
  j["file"] = "gnss.txt: stamp lat lon alt (deg, deg, m ellipsoidal) sigma_east sigma_north sigma_up (m)";
  if (bag)
    j["topic"] =
        "/gnss: sensor_msgs/NavSatFix, the fixes of gnss.txt (status GBAS_FIX, FIX for single point; diagonal "
        "covariance) and a NO_FIX message at each epoch without a fix";
  j["rate_hz"] = c.rate;
  j["quality"] = to_string(c.quality);
  j["sigma_horizontal_m"] = n.sigma_horizontal;
  j["sigma_vertical_m"] = n.sigma_vertical;
  j["error_correlation_s"] = n.correlation_s;
  j["error_model"] = "per axis first-order Gauss-Markov of the sigmas (white where the correlation is 0)";
  j["outlier_fraction"] = c.outlier_fraction;
  j["outliers"] = g.outliers;
  j["outlier_model"] = "multipath: 3-15 m horizontally in a uniform direction, -2 to 8 m up; sigmas as for the others";
  Json lever = Json::array();
  for (int a = 0; a < 3; ++a) lever.push_back(c.lever_arm[a]);
  j["lever_arm"] = lever;
  j["lever_arm_frame"] = "the antenna in the LiDAR frame, m";
  j["fixes"] = g.fixes.size();
  j["blocked"] = g.blocked;
  j["blocked_rule"] = "no fix while a structure (not a canopy) is within 200 m straight above the antenna";
  if (c.outage) {
    Json o = Json::array();
    o.push_back(c.outage->first);
    o.push_back(c.outage->second);
    j["outage_s"] = o;
    j["in_outage"] = g.in_outage;
  }
  return j;
}

void write_metadata(const fs::path& dir, const Simulator& sim, const SimulationConfig& config, const OutputOptions& out,
                    size_t total, const SimulatedGnss* gnss) {
  Trajectory gt;
  gt.format = TrajectoryFormat::kitti;
  const Eigen::Isometry3d T0_inv = sim.poses().front().inverse();
  for (const auto& T : sim.poses()) gt.poses.push_back(T0_inv * T);
  write_trajectory((dir / "poses.txt").string(), gt);
  gt.poses = sim.poses();
  write_trajectory((dir / "poses_world.txt").string(), gt);
  const double shift = out.mistake == TimeMistake::sweep_end ? 0.1 : 0.0;  // stamps at the end of each sweep
  write_file_atomic((dir / "times.txt").string(), [&](std::ostream& out) {
    char line[32];
    for (size_t k = 0; k < sim.num_frames(); ++k) {
      std::snprintf(line, sizeof(line), "%.6e\n", frame_stamp(k) + shift);
      out << line;
    }
  });
  const RealismConfig& r = sim.realism();
  Json j = Json::object();
  j["scenario"] = sim.scenario().name;
  j["description"] = sim.scenario().description;
  j["frames"] = sim.num_frames();
  j["seed"] = static_cast<unsigned long>(config.seed);
  j["sensor"] = sim.sensor().name;
  j["range_noise_sigma"] = config.noise;
  j["path_length_m"] = sim.path_length();
  j["rate_hz"] = 10.0;
  j["mean_points_per_scan"] = static_cast<double>(total) / sim.num_frames();
  j["motion_distortion"] = r.motion_distortion;
  j["poses"] = "poses.txt: ground-truth sensor poses, KITTI 3x4, first pose identity";
  if (config.route > 0) {  // route 0 keeps its historical file
    j["route"] = config.route;
    j["poses_world"] = "poses_world.txt: the same poses in the world frame shared by every route of this scenario and seed";
  }
  if (r.any()) {  // the ideal scenarios keep their historical file
    j["realism"] = r.to_string();
    j["stamp"] = "sweep_start";
    j["stamps"] =
        "times.txt and poses.txt are at the start of each sweep; points are in the sensor frame at their own firing time";
    if (r.motion_distortion && !out.bag)
      j["point_times"] = "point_times/NNNNNN.bin: float32 little-endian, one per point, seconds after the stamp, in [0, 0.1)";
    if (r.labels)
      j["labels"] = "labels/NNNNNN.label: uint32 per point, class (SemanticKITTI) | instance << 16; moving classes 252-259";
    if (r.moving_objects) j["moving_objects"] = sim.traffic().size();
  }
  if (out.bag) {
    j["bag"] = fs::path(simulated_bag_path(dir.string(), *out.bag)).filename().string();
    j["bag_format"] = bag_format_name(*out.bag);
    const bool livox = out.message == ScanMessage::livox_custom_msg;
    const std::string type = !livox                        ? "sensor_msgs/PointCloud2"
                             : *out.bag == BagFormat::ros1 ? "livox_ros_driver/CustomMsg"
                                                           : "livox_ros_driver2/msg/CustomMsg";
    j["topic"] = "/points: " + type + ", header stamps as in times.txt, recorded at the end of each sweep";
    j["point_time_field"] = livox                 ? "offset_time: uint32 ns after timebase, the header stamp (Livox CustomMsg)"
                            : r.motion_distortion ? time_field_note(out.time)
                                                  : "none";
    if (livox) j["reflectivity"] = "uint8, the simulated intensity in [0, 1] x 255, rounded";
  }
  if (out.imu) j["imu"] = imu_json(*out.imu, out);
  if (out.gnss && gnss) {
    Json origin = Json::object();
    origin["lat_deg"] = out.gnss->origin.lat_deg;
    origin["lon_deg"] = out.gnss->origin.lon_deg;
    origin["alt_m"] = out.gnss->origin.alt_m;
    j["geodetic_origin"] = origin;
    j["world_frame"] = "poses_world.txt: local ENU at geodetic_origin (x east, y north, z up; WGS84, ellipsoidal height)";
    j["gnss"] = gnss_json(*out.gnss, *gnss, out.bag.has_value());
  }
  write_file_atomic((dir / "scenario.json").string(), [&](std::ostream& out) { out << j.dump() << "\n"; });
}

void report_progress(size_t done, size_t total, double seconds, bool tty) {
  const double rate = done / std::max(seconds, 1e-9), eta = (total - done) / std::max(rate, 1e-9);
  if (tty) {
    std::fprintf(stderr, "\rsimulated %zu/%zu frames, %.1f frames/s, ETA %.0f s   ", done, total, rate, eta);
    if (done == total) std::fprintf(stderr, "\n");
  } else if (done % 500 == 0 || done == total) {
    spdlog::info("simulated {}/{} frames, {:.1f} frames/s, ETA {:.0f} s", done, total, rate, eta);
  }
}

}  // namespace

std::optional<BagFormat> parse_output_format(const std::string& text, const std::string& key) {
  if (text == "kitti") return std::nullopt;
  if (text == "mcap") return BagFormat::mcap;
  if (text == "db3") return BagFormat::db3;
  if (text == "bag") return BagFormat::ros1;
  throw Error(key + ": expected kitti, mcap, db3 or bag, got '" + text + "'");
}

PointTimeConvention parse_time_field(const std::string& text, const std::string& key) {
  if (text == "ouster") return PointTimeConvention::ouster_t;
  if (text == "velodyne") return PointTimeConvention::velodyne_time;
  if (text == "hesai") return PointTimeConvention::hesai_timestamp;
  if (text == "livox") return PointTimeConvention::livox_offset_time;
  throw Error(key + ": expected ouster, velodyne, hesai or livox, got '" + text + "'");
}

TimeMistake parse_time_mistake(const std::string& text, const std::string& key) {
  if (text == "none") return TimeMistake::none;
  if (text == "ms") return TimeMistake::milliseconds;
  if (text == "ns") return TimeMistake::nanoseconds;
  if (text == "absolute") return TimeMistake::absolute;
  if (text == "sweep_end") return TimeMistake::sweep_end;
  if (text == "zero") return TimeMistake::zero;
  throw Error(key + ": expected none, ms, ns, absolute, sweep_end or zero, got '" + text + "'");
}

ScanMessage parse_scan_message(const std::string& text, const std::string& key) {
  if (text == "pointcloud2") return ScanMessage::pointcloud2;
  if (text == "livox") return ScanMessage::livox_custom_msg;
  throw Error(key + ": expected pointcloud2 or livox, got '" + text + "'");
}

Compression parse_compression(const std::string& text, std::optional<BagFormat> bag, const std::string& key) {
  const Compression c = text == "none"   ? Compression::none
                        : text == "zstd" ? Compression::zstd
                        : text == "lz4"  ? Compression::lz4
                        : text == "bz2"  ? Compression::bz2
                                         : throw Error(key + ": expected none, zstd, lz4 or bz2, got '" + text + "'");
  const bool ok = c == Compression::none || (bag == BagFormat::mcap && c != Compression::bz2) ||
                  (bag == BagFormat::ros1 && c != Compression::zstd);
  if (!ok) throw Error(key + " " + text + ": mcap takes zstd or lz4, bag takes bz2 or lz4, kitti and db3 none");
  return c;
}

std::string simulated_bag_path(const std::string& dir, BagFormat format) {
  const char* name = format == BagFormat::mcap ? "drive.mcap" : format == BagFormat::ros1 ? "drive.bag" : "drive";
  return (fs::path(dir) / name).string();
}

size_t write_simulation(const std::string& dir_name, const SimulationConfig& config, bool quiet) {
  return write_simulation(dir_name, config, OutputOptions{}, quiet);
}

size_t write_simulation(const std::string& dir_name, const SimulationConfig& config, const OutputOptions& output, bool quiet) {
  Simulator sim(config);
  const fs::path dir(dir_name);
  FrameSink sink(dir, sim, output);
  // Frames in parallel in small batches (each scan is parallel inside too), written in order.
  const size_t batch = 8, n = sim.num_frames();
  const bool tty = !quiet && isatty(2);
  size_t total = 0;
  Stopwatch watch;
  std::vector<PointCloud> clouds(batch);
  for (size_t start = 0; start < n; start += batch) {
    const size_t count = std::min(batch, n - start);
    tbb::parallel_for(size_t(0), count, [&](size_t k) { clouds[k] = sim.scan(start + k); });
    for (size_t k = 0; k < count; ++k) {
      sink.write(start + k, clouds[k]);
      total += clouds[k].size();
    }
    if (!quiet) report_progress(start + count, n, watch.ms() / 1000.0, tty);
  }
  if (output.imu) {
    const SimulatedImu imu = simulate_imu(imu_trajectory(sim, output.imu->T_lidar_imu), *output.imu, config.seed);
    warn_unrealistic(imu.samples, sim);
    sink.write_imu(imu.samples, output.message == ScanMessage::livox_custom_msg);
    write_imu_txt((dir / "imu.txt").string(), imu.samples);
    write_imu_txt((dir / "imu_bias.txt").string(), imu.bias);
  }
  std::optional<SimulatedGnss> gnss;
  if (output.gnss) {
    gnss = simulate_gnss(sim, *output.gnss, config.seed);
    write_gnss_txt((dir / "gnss.txt").string(), gnss->fixes);
    sink.write_gnss(*gnss, output.gnss->quality);
  }
  sink.close();
  write_metadata(dir, sim, config, output, total, gnss ? &*gnss : nullptr);
  if (!quiet) {
    const std::string scans = output.bag ? fs::path(simulated_bag_path(dir_name, *output.bag)).filename().string() + " (/points)"
                                         : std::string("velodyne/") + (sim.realism().motion_distortion ? ", point_times/" : "");
    spdlog::info(
        "wrote {} scans ({:.0f} points each on average) of the '{}' scenario to {}: {}{}, poses.txt, "
        "poses_world.txt, times.txt, scenario.json{}",
        n, static_cast<double>(total) / n, sim.scenario().name, dir_name, scans, sim.realism().labels ? ", labels/" : "",
        output.imu ? ", imu.txt and imu_bias.txt (IMU at " + std::to_string(int(output.imu->rate)) + " Hz" +
                         (output.bag ? ", also as the bag's /imu)" : ")")
                   : "");
  }
  return total;
}

}  // namespace gcmap::sim
