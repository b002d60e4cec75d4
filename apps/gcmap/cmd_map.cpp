#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <iostream>

#include "commands.hpp"
#include "gcmap/core/error.hpp"
#include "gcmap/core/memory.hpp"
#include "gcmap/eval/map_entropy.hpp"
#include "gcmap/eval/trajectory_metrics.hpp"
#include "gcmap/io/point_cloud_io.hpp"
#include "gcmap/io/trajectory_io.hpp"
#include "gcmap/sim/simulator.hpp"
#include "gcmap/viz/run_pictures.hpp"
#include "map_runner.hpp"

namespace gcmap::cli {

namespace {

// Options shared by map and demo that override the config file.
struct Overrides {
  std::string config_file, global_mode, factor, elevation_calibration;
  int window = -1;
  double map_resolution = -1.0;
  bool pcd = false;
  bool no_explicit_loops = false;
  bool no_render = false;
  bool no_deskew = false, deskew_from_azimuth = false, no_elevation_estimate = false, no_imu = false;
  int threads = 0;
  std::string device = "auto";

  void add(CLI::App* cmd) {
    cmd->add_option("--device", device, "cpu, cuda or auto (a GPU when one answers)")->capture_default_str();
    cmd->add_option("--config", config_file, "YAML configuration (see `gcmap config`)");
    cmd->add_option("--global-mode", global_mode, "full (default) or sliding-window");
    cmd->add_option("--window", window, "sliding-window: predecessors each submap connects to (default 5)");
    cmd->add_option("--factor", factor, "vgicp (default) or se3 (relative-pose factors from scan matching)");
    cmd->add_option("--map-resolution", map_resolution, "Voxel size of map.ply in m (default 0.1)");
    cmd->add_flag("--pcd", pcd, "Also write map.pcd");
    cmd->add_flag("--no-explicit-loops", no_explicit_loops, "No ScanContext loop constraints (loop.enabled: false)");
    cmd->add_flag("--no-render", no_render, "Do not draw map.png (and, for demo, view.html and plots/)");
    cmd->add_flag("--no-deskew", no_deskew, "No motion compensation of scans with per-point times (preprocess.deskew: false)");
    cmd->add_flag(
        "--deskew-from-azimuth", deskew_from_azimuth,
        "Scans without per-point times: derive them from the azimuth of a spinning sensor (preprocess.deskew_from_azimuth)");
    cmd->add_flag("--no-imu", no_imu, "Ignore the IMU the input carries: map as without one (imu.use: false)");
    cmd->add_option("--elevation-calibration", elevation_calibration,
                    "Per-beam elevation offsets from `gcmap calibrate` (preprocess.elevation_calibration)");
    cmd->add_flag("--no-elevation-estimate", no_elevation_estimate,
                  "Map the scans as they are, without first estimating per-beam elevation offsets "
                  "(calibration.estimate_elevation: false)");
    cmd->add_option("--threads", threads, "Worker threads (0 = all cores)")->capture_default_str();
  }
  MappingConfig resolve() const {
    MappingConfig c = config_file.empty() ? MappingConfig{} : MappingConfig::load(config_file);
    if (!global_mode.empty()) c.global.mode = parse_global_mode(global_mode, "--global-mode");
    if (!factor.empty()) c.global.factor = parse_factor_source(factor, "--factor");
    if (window >= 0) c.global.window = window;
    if (map_resolution >= 0) c.output.map_resolution = map_resolution;
    if (pcd) c.output.pcd = true;
    if (no_explicit_loops) c.loop.enabled = false;
    if (no_deskew) c.preprocess.deskew = false;
    if (deskew_from_azimuth) c.preprocess.deskew_from_azimuth = true;
    if (!elevation_calibration.empty()) c.preprocess.elevation_calibration = elevation_calibration;
    if (no_elevation_estimate) c.calibration.estimate_elevation = false;
    if (no_imu) c.imu.use = false;
    try {
      c.validate();
    } catch (const Error& e) { throw Error(std::string("bad option: ") + e.what()); }
    return c;
  }
};

}  // namespace

void add_map(CLI::App& app, Runner& run) {
  auto opt = std::make_shared<MapRunOptions>();
  auto ov = std::make_shared<Overrides>();
  auto* cmd = app.add_subcommand("map", "Map a LiDAR sequence: odometry, submaps, global matching-cost optimization");
  cmd->add_option("input", opt->input,
                  "KITTI sequence folder (velodyne/*.bin ...), a folder of .bin/.pcd/.ply scans, or a ROS bag (.mcap, .db3 or "
                  "its folder, .bag)")
      ->required();
  cmd->add_option("--topic", opt->topic, "Bags: the point-cloud topic (default: the only one)");
  cmd->add_option("--start-time", opt->start_time, "Bags: start this many seconds after the first message");
  cmd->add_option("--duration", opt->duration, "Bags: map this many seconds (0 = to the end)");
  cmd->add_option("-o,--output", opt->output, "Output folder")->required();
  cmd->add_option("--times", opt->times_file,
                  "Folders: the scans' stamps, one line per scan (default: times.txt in the sequence folder, in the scans folder "
                  "or beside it)");
  cmd->add_option("--gnss", opt->gnss_file,
                  "GNSS fixes (stamp lat lon alt sigma_e sigma_n sigma_u per line; default: gnss.txt beside the scans, else a "
                  "bag's only sensor_msgs/NavSatFix topic): the map in local ENU, trajectory_utm.txt and trajectory_wgs84.txt");
  cmd->add_option("--gnss-topic", opt->gnss_topic,
                  "Bags: the sensor_msgs/NavSatFix topic of the fixes (epochs without a fix skipped; sigmas from the "
                  "covariance)");
  cmd->add_option("--imu", opt->imu_file,
                  "IMU samples (stamp gx gy gz ax ay az per line, rad/s and m/s^2 or g; default: imu.txt beside the scans, else "
                  "a bag's only sensor_msgs/Imu topic): its gyro deskews the sweeps (see the imu: config section)");
  cmd->add_option("--imu-topic", opt->imu_topic, "Bags: the sensor_msgs/Imu topic (when the bag has several)");
  auto bin_fields = std::make_shared<std::string>("xyzi");
  cmd->add_option("--bin-fields", *bin_fields, "Layout of .bin scans: xyzi (KITTI) or xyz")->capture_default_str();
  cmd->add_option("--initial-trajectory", opt->initial_trajectory, "KITTI or TUM poses to use instead of the built-in odometry");
  cmd->add_option("--start", opt->start, "First scan index")->capture_default_str();
  cmd->add_option("--max-frames", opt->max_frames, "Process at most this many scans (0 = all)")->capture_default_str();
  cmd->add_flag("--quiet", opt->quiet, "No progress line");
  ov->add(cmd);
  cmd->footer("Writes trajectory.kitti/.tum, odometry.kitti, map.ply, graph.json, stats.json, config.yaml and session/.");
  cmd->callback([opt, ov, bin_fields, &run] {
    run = [opt, ov, bin_fields] {
      const auto threads = limit_threads(ov->threads);
      opt->bin_fields = parse_bin_fields(*bin_fields);
      opt->config = ov->resolve();
      opt->device = parse_device(ov->device, "--device");
      const MapRunResult r = run_mapping(*opt);
      if (r.nothing_written) {
        std::fprintf(stderr, "Interrupted while estimating the beam elevations: nothing mapped, nothing written.\n");
        return 128 + r.signal;
      }
      std::printf("{\"frames\":%zu,\"submaps\":%zu,\"factors\":%zu,\"seconds\":%.3f,\"frames_per_second\":%.2f}\n", r.frames,
                  r.submaps, r.factors, r.seconds, r.fps);
      std::fprintf(stderr, "%s %zu frames in %.1f s (%.1f frames/s): %zu submaps, %zu global factors; peak memory %.0f MB.\n",
                   r.signal ? "Interrupted: mapped" : "Mapped", r.frames, r.seconds, r.fps, r.submaps, r.factors,
                   peak_rss_bytes() / 1e6);
      std::fprintf(stderr,
                   "Wrote %s: trajectory.kitti and .tum (optimized poses), odometry.kitti, map.ply%s, graph.json, stats.json%s, "
                   "quality.json and report.html (run quality, verdict first), config.yaml%s, session/ (for localize and merge).\n",
                   opt->output.c_str(), opt->config.output.pcd ? " and map.pcd" : "", r.signal ? " (marked partial)" : "",
                   r.elevation_calibration ? ", elevation_calibration.txt (the beam offsets applied)" : "");
      if (!ov->no_render)
        for (const auto& f : viz::write_run_pictures(opt->output, {}))
          std::fprintf(stderr, "Wrote %s: %s.\n", f.path.c_str(), f.what.c_str());
      if (!r.gnss.empty()) std::fprintf(stderr, "%s\n", r.gnss.c_str());
      if (!r.imu.empty()) std::fprintf(stderr, "%s\n", r.imu.c_str());
      if (!r.failure.empty()) std::fprintf(stderr, "gcmap: %s\n", r.failure.c_str());
      return r.signal ? 128 + r.signal : r.failure.empty() ? 0 : 2;
    };
  });
}

void add_demo(CLI::App& app, Runner& run) {
  struct Options {
    std::string output, scenario = "small";
    int frames = 0;
    uint64_t seed = 1;
  };
  auto opt = std::make_shared<Options>();
  auto ov = std::make_shared<Overrides>();
  auto* cmd = app.add_subcommand("demo", "Simulate a scenario, map it, and report accuracy against ground truth");
  cmd->add_option("-o,--output", opt->output, "Working folder (default: a temporary folder, removed afterwards)");
  cmd->add_option("--scenario", opt->scenario, "small, loop, corridor, city, highway or forest")->capture_default_str();
  cmd->add_option("--frames", opt->frames, "Number of frames (0 = the scenario's default)")->capture_default_str();
  cmd->add_option("--seed", opt->seed, "Simulation seed")->capture_default_str();
  ov->add(cmd);
  cmd->callback([opt, ov, &run] {
    run = [opt, ov] {
      namespace fs = std::filesystem;
      const auto threads = limit_threads(ov->threads);
      const bool temporary = opt->output.empty();
      const fs::path dir =
          temporary ? fs::temp_directory_path() / ("gcmap_demo_" + std::to_string(::getpid())) : fs::path(opt->output);
      struct Cleanup {
        fs::path p;
        bool on;
        ~Cleanup() {
          std::error_code ec;
          if (on) fs::remove_all(p, ec);
        }
      } cleanup{dir, temporary};
      sim::SimulationConfig sc;
      sc.scenario = opt->scenario;
      sc.frames = opt->frames;
      sc.seed = opt->seed;
      std::printf("gcmap demo: simulating the '%s' scenario...\n", sc.scenario.c_str());
      std::fflush(stdout);
      sim::write_simulation((dir / "sim").string(), sc);
      MapRunOptions mo;
      mo.input = (dir / "sim").string();
      mo.output = (dir / "map").string();
      mo.config = ov->resolve();
      mo.device = parse_device(ov->device, "--device");
      mo.quiet = false;
      std::printf("mapping %s ...\n", mo.input.c_str());
      std::fflush(stdout);
      const MapRunResult r = run_mapping(mo);
      if (r.nothing_written) return 128 + r.signal;
      const Poses gt = read_trajectory((dir / "sim" / "poses.txt").string()).poses;
      const Poses odom = read_trajectory((dir / "map" / "odometry.kitti").string()).poses;
      const Poses est = read_trajectory((dir / "map" / "trajectory.kitti").string()).poses;
      const KittiError ko = kitti_relative_error(gt, odom), ke = kitti_relative_error(gt, est);
      const AbsoluteError ao = absolute_trajectory_error(gt, odom), ae = absolute_trajectory_error(gt, est);
      const MapEntropy mme = mean_map_entropy(read_point_cloud((dir / "map" / "map.ply").string()));
      std::printf("\n%-28s %12s %12s\n", "", "odometry", "global");
      std::printf("%-28s %12.3f %12.3f\n", "ATE RMSE [m]", ao.rmse, ae.rmse);
      std::printf("%-28s %12.3f %12.3f\n", "ATE max [m]", ao.max, ae.max);
      if (ke.num_segments) {
        std::printf("%-28s %12.3f %12.3f\n", "KITTI translation [%]", ko.translation_percent, ke.translation_percent);
        std::printf("%-28s %12.4f %12.4f\n", "KITTI rotation [deg/100m]", ko.rotation_deg_per_100m, ke.rotation_deg_per_100m);
      } else {
        std::printf("%-28s %s\n", "KITTI relative error", "n/a (trajectory shorter than 100 m)");
      }
      std::printf("%-28s %12.3f\n", "mean map entropy", mme.mean);
      std::printf("%-28s %12zu\n", "frames", r.frames);
      std::printf("%-28s %12zu\n", "submaps", r.submaps);
      std::printf("%-28s %12zu\n", "global factors", r.factors);
      std::printf("%-28s %12.2f\n", "frames per second", r.fps);
      std::printf("%-28s %12.0f\n", "peak memory [MB]", peak_rss_bytes() / 1e6);
      if (!ov->no_render && !temporary) {
        viz::RunPicturesOptions po;
        po.view_html = po.plots = true;
        po.plot.ground_truth = (dir / "sim" / "poses.txt").string();
        std::printf("pictures:\n");
        for (const auto& f : viz::write_run_pictures(mo.output, po)) std::printf("  %s: %s\n", f.path.c_str(), f.what.c_str());
      }
      std::printf("outputs: %s\n", temporary ? "(temporary, removed; give -o DIR to keep them and their pictures)"
                                             : (dir / "map").string().c_str());
      return 0;
    };
  });
}

void add_config(CLI::App& app, Runner& run) {
  struct Options {
    std::string file;
    bool describe = false, markdown = false;
  };
  auto opt = std::make_shared<Options>();
  auto* cmd = app.add_subcommand("config", "Print the effective mapping configuration as YAML, or describe every key");
  auto* file = cmd->add_option("--config", opt->file, "Load this YAML first (validates it: every key in its range)");
  auto* describe =
      cmd->add_flag("--describe", opt->describe, "Every key's type, default, unit, range, module and meaning")->excludes(file);
  cmd->add_flag("--markdown", opt->markdown, "With --describe: as Markdown (docs/config.md)")->needs(describe);
  cmd->callback([opt, &run] {
    run = [opt] {
      if (opt->describe) std::cout << (opt->markdown ? config_reference_markdown() : config_reference_text());
      else std::cout << (opt->file.empty() ? MappingConfig{} : MappingConfig::load(opt->file)).to_yaml();
      return 0;
    };
  });
}

}  // namespace gcmap::cli
