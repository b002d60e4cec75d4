// gcmap inspect: what a recording holds and what `gcmap map` will assume about it, before mapping.
#include <cstdio>
#include <iostream>

#include "commands.hpp"
#include "gcmap/io/inspect.hpp"
#include "gcmap/mapping/config.hpp"

namespace gcmap::cli {

void add_inspect(CLI::App& app, Runner& run) {
  struct Options {
    std::string input, config_file, times_file, topic, bin_fields = "xyzi";
    bool json = false;
    size_t sample = 20;
  };
  auto opt = std::make_shared<Options>();
  auto* cmd = app.add_subcommand(
      "inspect", "Read a recording (not a map) and report its stamps, per-point times, sensor and what `map` will assume");
  cmd->add_option("input", opt->input, "KITTI sequence folder, a folder of .bin/.pcd/.ply scans, or a ROS bag")->required();
  cmd->add_flag("--json", opt->json, "Machine-readable output");
  cmd->add_option("--config", opt->config_file, "The YAML configuration `map` will use (deskewing, corrections)");
  cmd->add_option("--times", opt->times_file, "Folders: the scans' stamps, as `map --times`");
  cmd->add_option("--topic", opt->topic, "Bags: the point-cloud topic (default: the only one)");
  cmd->add_option("--bin-fields", opt->bin_fields, "Layout of .bin scans: xyzi (KITTI) or xyz")->capture_default_str();
  cmd->add_option("--sample", opt->sample, "Scans whose points are read, spread over the recording")->capture_default_str();
  cmd->callback([opt, &run] {
    run = [opt] {
      const MappingConfig c = opt->config_file.empty() ? MappingConfig{} : MappingConfig::load(opt->config_file);
      const PreprocessConfig& pc = c.preprocess;
      InspectOptions io;
      io.input = InputOptions{.times_file = opt->times_file,
                              .bin_fields = parse_bin_fields(opt->bin_fields),
                              .topic = opt->topic,
                              .kitti_vertical_correction = pc.kitti_vertical_correction,
                              .deskew = pc.deskew,
                              .deskew_from_azimuth = pc.deskew_from_azimuth,
                              .elevation_calibration = pc.elevation_calibration,
                              .estimate_elevation_frames = c.calibration.estimate_elevation ? c.calibration.frames : 0,
                              .gnss_file = "",
                              .gnss_topic = "",
                              .use_imu = c.imu.use,
                              .imu_levels_map = c.imu.level_map,
                              .imu_inertial_odometry = c.imu.inertial_odometry,
                              .imu_file = "",
                              .imu_topic = ""};
      io.sample_scans = opt->sample;
      const InspectReport r = inspect_recording(opt->input, io);
      if (opt->json) std::printf("%s\n", r.to_json().dump().c_str());
      else std::printf("%s", r.text().c_str());
      return 0;
    };
  });
}

}  // namespace gcmap::cli
