#include <cmath>
#include <cstdlib>
#include <iostream>
#include <optional>
#include <sstream>
#include <vector>

#include "commands.hpp"
#include "gcmap/core/error.hpp"
#include "gcmap/core/timer.hpp"
#include "gcmap/sim/writer.hpp"

namespace gcmap::cli {

namespace {

// --imu and the options that shape it.
struct ImuOptions {
  bool enabled = false, noise_free = false;
  sim::ImuSimConfig config;
  CLI::Option *rate = nullptr, *offset = nullptr, *ideal = nullptr, *gyro_noise = nullptr, *accel_noise = nullptr;

  void add(CLI::App* cmd) {
    cmd->add_flag("--imu", enabled,
                  "Also an IMU: imu.txt (stamp, gyro rad/s, acceleration m/s^2), imu_bias.txt, and a bag's /imu "
                  "(sensor_msgs/Imu; acceleration in g with --message livox); scenario.json gives its noise, T_lidar_imu "
                  "and time offset");
    rate = cmd->add_option("--imu-rate", config.rate, "IMU sample rate in Hz")->capture_default_str();
    offset = cmd->add_option("--imu-time-offset", config.time_offset,
                             "IMU stamps = true time + this (s): the IMU clock's offset from the LiDAR's")
                 ->capture_default_str();
    ideal = cmd->add_flag("--imu-noise-free", noise_free, "An exact IMU: no white noise, no bias");
    gyro_noise = cmd->add_option("--imu-gyro-noise", config.density.gyro_noise,
                                 "Gyro white noise density, rad/s/sqrt(Hz) (MEMS gyro datasheets give 0.5e-4 to 2.4e-4)")
                     ->capture_default_str();
    accel_noise =
        cmd->add_option("--imu-accel-noise", config.density.accel_noise, "Accelerometer white noise density, m/s^2/sqrt(Hz)")
            ->capture_default_str();
  }
  std::optional<sim::ImuSimConfig> resolve() {
    for (const CLI::Option* o : {rate, offset, ideal, gyro_noise, accel_noise})
      if (!enabled && o->count()) throw Error(o->get_name() + " needs --imu");
    if (!enabled) return std::nullopt;
    if (!(config.rate >= 10.0 && config.rate <= 10000.0))
      throw Error("--imu-rate: expected 10 to 10000 Hz, got " + std::to_string(config.rate));
    if (!(config.density.gyro_noise >= 0.0 && config.density.gyro_noise <= 0.1))
      throw Error("--imu-gyro-noise: expected 0 to 0.1 rad/s/sqrt(Hz), got " + std::to_string(config.density.gyro_noise));
    if (!(config.density.accel_noise >= 0.0 && config.density.accel_noise <= 1.0))
      throw Error("--imu-accel-noise: expected 0 to 1 m/s^2/sqrt(Hz), got " + std::to_string(config.density.accel_noise));
    if (noise_free && (gyro_noise->count() || accel_noise->count()))
      throw Error("--imu-noise-free has no noise: --imu-gyro-noise and --imu-accel-noise contradict it");
    config.noise = !noise_free;
    return config;
  }
};

// --gnss and the options that shape it.
struct GnssOptions {
  bool enabled = false;
  sim::GnssSimConfig config;
  std::string quality = "rtk", lever_arm, origin, outage;
  std::vector<CLI::Option*> shaping;

  void add(CLI::App* cmd) {
    cmd->add_flag("--gnss", enabled,
                  "Also GNSS fixes: gnss.txt (stamp lat lon alt sigma_e sigma_n sigma_u); the world (poses_world.txt) is "
                  "local ENU at --gnss-origin, given in scenario.json with the receiver model");
    shaping.push_back(cmd->add_option("--gnss-rate", config.rate, "Fixes per second")->capture_default_str());
    shaping.push_back(cmd->add_option("--gnss-quality", quality,
                                      "rtk (1.5 cm horizontal, 2.5 cm vertical, white), float (0.3 / 0.5 m, correlated over "
                                      "10 s) or single (2 / 3 m, correlated over 30 s)")
                          ->capture_default_str());
    shaping.push_back(cmd->add_option("--gnss-outliers", config.outlier_fraction,
                                      "Fraction of fixes with a multipath error (3-15 m horizontally, -2 to 8 m up)")
                          ->capture_default_str());
    shaping.push_back(cmd->add_option("--gnss-lever-arm", lever_arm, "X,Y,Z: the antenna in the LiDAR frame, m (default 0,0,0)"));
    shaping.push_back(
        cmd->add_option("--gnss-origin", origin, "LAT,LON,ALT of the world origin (default 48.137154,11.576124,520)"));
    shaping.push_back(cmd->add_option("--gnss-outage", outage, "FROM,TO: no fixes between these seconds (a dropout stretch)"));
  }
  std::optional<sim::GnssSimConfig> resolve() {
    for (CLI::Option* o : shaping)
      if (!enabled && o->count()) throw Error(o->get_name() + " needs --gnss");
    if (!enabled) return std::nullopt;
    if (!(config.rate > 0.0 && config.rate <= 100.0))
      throw Error("--gnss-rate: expected 0 to 100 Hz, got " + std::to_string(config.rate));
    if (!(config.outlier_fraction >= 0.0 && config.outlier_fraction <= 0.5))
      throw Error("--gnss-outliers: expected a fraction in [0, 0.5], got " + std::to_string(config.outlier_fraction));
    config.quality = sim::parse_gnss_quality(quality, "--gnss-quality");
    if (!lever_arm.empty()) config.lever_arm = triple("--gnss-lever-arm", lever_arm);
    if (!origin.empty()) config.origin = parse_geodetic("--gnss-origin", origin);
    if (!outage.empty()) {
      const Eigen::Vector2d w = pair("--gnss-outage", outage);
      if (!(w[1] > w[0])) throw Error("--gnss-outage: TO must be after FROM, got \"" + outage + "\"");
      config.outage = std::make_pair(w[0], w[1]);
    }
    return config;
  }

 private:
  static std::vector<double> numbers(const std::string& option, const std::string& text, size_t n) {
    std::vector<double> v;
    std::stringstream ss(text);
    std::string item;
    bool bad = false;
    while (std::getline(ss, item, ',')) {
      char* end = nullptr;
      const double x = std::strtod(item.c_str(), &end);
      bad |= item.empty() || *end != '\0' || !std::isfinite(x);
      v.push_back(x);
    }
    if (bad || v.size() != n)
      throw Error(option + ": expected " + std::to_string(n) + " comma-separated numbers, got \"" + text + "\"");
    return v;
  }
  static Eigen::Vector3d triple(const std::string& option, const std::string& text) {
    const std::vector<double> v = numbers(option, text, 3);
    return {v[0], v[1], v[2]};
  }
  static Eigen::Vector2d pair(const std::string& option, const std::string& text) {
    const std::vector<double> v = numbers(option, text, 2);
    return {v[0], v[1]};
  }
};

}  // namespace

void add_simulate(CLI::App& app, Runner& run) {
  auto opt = std::make_shared<sim::SimulationConfig>();
  auto out = std::make_shared<std::string>();
  auto realism = std::make_shared<std::string>();
  auto ideal = std::make_shared<bool>(false);
  auto format = std::make_shared<std::string>("kitti"), time_field = std::make_shared<std::string>("ouster"),
       compression = std::make_shared<std::string>("none"), message = std::make_shared<std::string>("pointcloud2"),
       mistake = std::make_shared<std::string>("none");
  auto* cmd =
      app.add_subcommand("simulate", "Generate a synthetic LiDAR sequence with exact ground truth (KITTI layout or a ROS bag)");
  cmd->add_option("-o,--output", *out,
                  "Output folder: velodyne/ (kitti) or the bag drive.mcap, drive/ (db3: rosbag2 folder) or drive.bag, "
                  "with poses.txt, times.txt, scenario.json (and labels/) beside it")
      ->required();
  cmd->add_option("--format", *format,
                  "kitti, mcap, db3 or bag (ROS 1): a bag holds /points (sensor_msgs/PointCloud2 or, with --message "
                  "livox, Livox CustomMsg; header stamps as in times.txt)")
      ->capture_default_str();
  auto* message_opt =
      cmd->add_option("--message", *message,
                      "Bags: the scans as pointcloud2 (sensor_msgs/PointCloud2) or livox (Livox CustomMsg: "
                      "livox_ros_driver/CustomMsg in a ROS 1 bag, livox_ros_driver2/msg/CustomMsg in mcap and db3; "
                      "offset_time in ns after timebase = the stamp, reflectivity = 255 x intensity)")
          ->capture_default_str();
  auto* time_opt =
      cmd->add_option("--time-field", *time_field,
                      "PointCloud2 bags, with motion distortion: the per-point time as ouster (t, uint32 ns), velodyne (time, "
                      "float32 s), hesai (timestamp, float64 absolute s) or livox (offset_time, uint32 ns)")
          ->capture_default_str();
  auto* compression_opt = cmd->add_option("--compression", *compression, "Bag chunks: none; mcap: zstd or lz4; bag: bz2 or lz4")
                              ->capture_default_str();
  cmd->add_option("--time-mistake", *mistake,
                  "Write the per-point times wrong on purpose, as real recordings do (to test inspect and map): ms, ns "
                  "(units where s are expected), absolute (s on a clock started 1000 s before the drive, where s after the stamp "
                  "are expected), "
                  "sweep_end (stamps at the end of each sweep) or zero; other than zero: kitti or --time-field velodyne")
      ->capture_default_str();
  cmd->add_option("--scenario", opt->scenario,
                  "loop, small, corridor (ideal by default), tunnel, city, highway, forest, handheld (realistic by "
                  "default)")
      ->capture_default_str();
  cmd->add_option("--frames", opt->frames,
                  "Number of frames (0 = the scenario's default; city, highway, forest: the first N frames of the drive)")
      ->capture_default_str();
  cmd->add_option("--seed", opt->seed, "World and noise seed")->capture_default_str();
  cmd->add_option("--route", opt->route,
                  "Which route through the seed's world: city and small have 0-2, loop 0-1 (noise and traffic differ per "
                  "route; poses_world.txt gives the poses in the shared world frame)")
      ->capture_default_str();
  cmd->add_option("--sensor", opt->sensor,
                  "hdl64, vlp16, os1-64, os1-128, avia (Livox-Avia-like rosette) or mid360 (Livox-Mid-360-like, 360 x 59 deg, "
                  "non-repetitive); default: mid360 for --scenario handheld, hdl64 otherwise");
  cmd->add_option("--noise", opt->noise, "Range noise sigma in m")->capture_default_str();
  cmd->add_flag("--ideal", *ideal, "No realism: scans at one instant, static world, Gaussian range noise only");
  cmd->add_option("--realism", *realism,
                  "all, none, or the keys to enable: motion_distortion, moving_objects, labels, calibration, "
                  "range_noise, dropouts, mixed_pixels, spurious, curbs, vegetation (default: the scenario's)");
  auto imu = std::make_shared<ImuOptions>();
  imu->add(cmd);
  auto gnss = std::make_shared<GnssOptions>();
  gnss->add(cmd);
  cmd->callback([=, &run] {
    run = [=] {
      if (*ideal && !realism->empty()) throw Error("--ideal and --realism: give one of them");
      if (*ideal) opt->realism = sim::RealismConfig::none();
      if (!realism->empty()) opt->realism = sim::parse_realism(*realism);
      sim::OutputOptions output;
      output.bag = sim::parse_output_format(*format, "--format");
      if (!output.bag && (time_opt->count() || compression_opt->count() || message_opt->count()))
        throw Error("--time-field, --compression and --message apply to bags (--format mcap, db3 or bag), not to kitti");
      output.message = sim::parse_scan_message(*message, "--message");
      if (output.message == sim::ScanMessage::livox_custom_msg && time_opt->count())
        throw Error("--time-field picks a PointCloud2 field: --message livox has its own (offset_time, ns)");
      output.time = sim::parse_time_field(*time_field, "--time-field");
      output.compression = sim::parse_compression(*compression, output.bag, "--compression");
      output.imu = imu->resolve();
      output.gnss = gnss->resolve();
      output.mistake = sim::parse_time_mistake(*mistake, "--time-mistake");
      Stopwatch w;
      const size_t points = sim::write_simulation(*out, *opt, output, false);
      const std::string bag = output.bag ? ",\"bag\":\"" + sim::simulated_bag_path(*out, *output.bag) + "\"" : "";
      std::cout << "{\"output\":\"" << *out << "\"" << bag << ",\"points\":" << points << ",\"seconds\":" << w.ms() / 1000.0
                << "}\n";
      return 0;
    };
  });
}

}  // namespace gcmap::cli
