#include <spdlog/spdlog.h>

#include <filesystem>

#include "commands.hpp"
#include "gcmap/core/error.hpp"
#include "gcmap/core/memory.hpp"
#include "gcmap/cuda/cuda_backend.hpp"
#include "gcmap/io/file.hpp"
#include "gcmap/io/trajectory_io.hpp"
#include "gcmap/session/localizer.hpp"
#include "gcmap/session/session.hpp"
#include "map_runner.hpp"
#include "progress.hpp"

namespace gcmap::cli {

namespace {

namespace fs = std::filesystem;

struct LocalizeOptions {
  MapRunOptions input;  // the scans: input, start, max_frames, quiet and the bag options
  std::string map, output, initial_pose, config_file, device = "auto";
  bool global_init = false;
  bool map_calibration = true;  // --no-map-calibration turns it off
  int threads = 0;
};

// The beam offsets the map was made with (elevation_calibration.txt beside its session): the scans
// must be corrected as the map's were to match it, so the same sensor is assumed. Not when the
// config names a file of its own (with_elevation_calibration loads that) or --no-map-calibration.
std::shared_ptr<const ElevationCalibration> map_calibration(const LocalizeOptions& o, const std::string& session,
                                                            const MappingConfig& config, std::string& said) {
  fs::path dir(session);
  if (!dir.has_filename()) dir = dir.parent_path();  // "out/session/"
  const fs::path file = dir.parent_path() / "elevation_calibration.txt";
  if (!config.preprocess.elevation_calibration.empty()) said = "the config's " + config.preprocess.elevation_calibration;
  else if (!o.map_calibration) said = "none (--no-map-calibration)";
  else if (!fs::exists(file)) said = "none (the map was made without beam offsets)";
  else {
    said = "the map's " + file.string() + " (the same sensor assumed; --no-map-calibration to map the scans as they are)";
    return std::make_shared<const ElevationCalibration>(ElevationCalibration::load(file.string()));
  }
  return nullptr;
}

Json frames_json(const std::vector<LocalizedFrame>& frames, int start) {
  Json all = Json::array();
  for (const LocalizedFrame& f : frames) {
    Json j = Json::object();
    j["frame"] = f.index + start;
    j["status"] = to_string(f.status);
    j["map_overlap"] = f.map_overlap;
    j["prior_submaps"] = f.prior_submaps;
    j["deskewed"] = f.deskewed;
    j["ms"] = f.ms;
    all.push_back(j);
  }
  return all;
}

int localize(const LocalizeOptions& o) {
  const auto threads = limit_threads(o.threads);
  if (!o.initial_pose.empty() && o.global_init) throw Error("--initial-pose and --global-init exclude each other");
  if (o.initial_pose.empty() && !o.global_init) throw Error("give --initial-pose \"x y z qx qy qz qw\" or --global-init");
  const std::string folder = fs::exists(fs::path(o.map) / "session") ? (fs::path(o.map) / "session").string() : o.map;
  Progress loading("loading " + folder + ": submap", 0, o.input.quiet);
  Session s = read_session(folder, loading.callback());
  loading.finish();
  MappingConfig config = o.config_file.empty() ? s.config : MappingConfig::load(o.config_file);
  config.global.voxel_resolution = s.config.global.voxel_resolution;  // the prior's voxel maps are at it
  Input input = open_input(o.input);
  ScanSource& source = *input.source;
  fs::create_directories(o.output);
  auto prior = std::make_shared<PriorMap>(PriorMap{std::move(s.submaps), std::move(s.T_world_submap)});
  std::string calibration;
  auto offsets = map_calibration(o, folder, config, calibration);
  if (!o.input.quiet) spdlog::info("beam calibration: {}", calibration);
  Localizer localizer(prior, config, cuda::make_backend(parse_device(o.device, "--device")),
                      PipelineOptions{.kitti_hdl64 = input.kitti_hdl64, .elevation_calibration = std::move(offsets)});
  if (!o.initial_pose.empty()) localizer.set_initial_pose(parse_pose_option("--initial-pose", o.initial_pose));
  Progress progress("frame", source.size_hint(), o.input.quiet);
  size_t tracking = 0;
  double overlap = 0;
  while (auto r = source.next()) {
    PointCloud scan;
    try {
      scan = r->load();
    } catch (const Error& e) { spdlog::warn("skipping scan: {}", e.what()); }
    const LocalizedFrame f = localizer.add_scan(std::move(scan), r->stamp);
    tracking += f.status != LocalizationStatus::lost;
    overlap += f.map_overlap;
    progress.update(f.index + 1, std::string("status ") + to_string(f.status));
  }
  progress.finish();
  const auto& frames = localizer.frames();
  Trajectory t;
  for (const LocalizedFrame& f : frames) {
    t.poses.push_back(f.T_map_frame);
    t.stamps.push_back(f.stamp);
  }
  write_trajectory((fs::path(o.output) / "trajectory.kitti").string(), t);
  t.format = TrajectoryFormat::tum;
  write_trajectory((fs::path(o.output) / "trajectory.tum").string(), t);
  Json report = Json::object();
  report["frames"] = frames.size();
  report["beam_calibration"] = calibration;
  report["tracked_fraction"] = frames.empty() ? 0.0 : double(tracking) / frames.size();
  report["mean_map_overlap"] = frames.empty() ? 0.0 : overlap / frames.size();
  report["seconds"] = progress.seconds();
  report["peak_rss_mb"] = peak_rss_bytes() / 1e6;
  Json warnings = Json::array();  // e.g. a truncated bag: localized up to the damage
  for (const std::string& w : source.warnings()) warnings.push_back(w);
  report["input_warnings"] = warnings;
  report["per_frame"] = frames_json(frames, input.frame_offset);
  write_file_atomic((fs::path(o.output) / "localization.json").string(),
                    [&](std::ostream& out) { out << report.dump() << "\n"; });
  std::fprintf(stderr,
               "Localized %zu frames in %.1f s: %zu held by the map (%.0f %%), %.0f %% of points on average had no map "
               "correspondence; peak memory %.0f MB.\n",
               frames.size(), progress.seconds(), tracking, frames.empty() ? 0.0 : 100.0 * tracking / frames.size(),
               frames.empty() ? 0.0 : 100.0 * (1.0 - overlap / frames.size()), peak_rss_bytes() / 1e6);
  std::fprintf(stderr, "Wrote %s: trajectory.kitti and .tum (in the map's frame), localization.json (per-frame status).\n",
               o.output.c_str());
  return 0;
}

}  // namespace

void add_localize(CLI::App& app, Runner& run) {
  auto o = std::make_shared<LocalizeOptions>();
  auto* cmd = app.add_subcommand("localize", "Track a sequence on a prior map (the session of an earlier gcmap map run)");
  cmd->add_option("--map", o->map, "Output folder of gcmap map (or its session/ folder)")->required();
  cmd->add_option("input", o->input.input,
                  "Sequence folder (KITTI layout or a folder of scans) or a ROS bag (.mcap, .db3 or its folder, .bag)")
      ->required();
  cmd->add_option("--topic", o->input.topic, "Bags: the point-cloud topic (default: the only one)");
  cmd->add_option("--start-time", o->input.start_time, "Bags: start this many seconds after the first message");
  cmd->add_option("--duration", o->input.duration, "Bags: localize this many seconds (0 = to the end)");
  cmd->add_option("-o,--output", o->output, "Output folder")->required();
  cmd->add_option("--initial-pose", o->initial_pose, "First frame's pose in the map: \"x y z qx qy qz qw\"");
  cmd->add_flag("--global-init", o->global_init, "Find the first pose by ScanContext place recognition and GICP");
  cmd->add_option("--config", o->config_file, "YAML configuration (default: the prior session's)");
  cmd->add_flag(
      "--no-map-calibration", [o](int64_t) { o->map_calibration = false; },
      "Do not correct the scans by the map's elevation_calibration.txt (the beam offsets it was made with)");
  cmd->add_option("--start", o->input.start, "First scan index")->capture_default_str();
  cmd->add_option("--max-frames", o->input.max_frames, "Process at most this many scans (0 = all)")->capture_default_str();
  cmd->add_option("--device", o->device, "cpu, cuda or auto")->capture_default_str();
  cmd->add_option("--threads", o->threads, "Worker threads (0 = all cores)")->capture_default_str();
  cmd->add_flag("--quiet", o->input.quiet, "No progress line");
  cmd->callback([o, &run] { run = [o] { return localize(*o); }; });
}

}  // namespace gcmap::cli
