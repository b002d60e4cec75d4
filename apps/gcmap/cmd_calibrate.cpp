// gcmap calibrate: per-beam elevation offsets of a spinning LiDAR from a recording and the
// trajectory of a mapping run on it (calibration/elevation_calibration.hpp).
#include <spdlog/spdlog.h>
#include <tbb/parallel_for.h>

#include <cmath>
#include <cstdio>

#include "commands.hpp"
#include "gcmap/calibration/elevation_calibration.hpp"
#include "gcmap/core/error.hpp"
#include "gcmap/core/se3.hpp"
#include "gcmap/io/file.hpp"
#include "gcmap/io/trajectory_io.hpp"
#include "gcmap/mapping/pipeline.hpp"
#include "map_runner.hpp"
#include "progress.hpp"

namespace gcmap::cli {

namespace {

struct CalibrateOptions {
  MapRunOptions input;
  std::string trajectory, output, config_file;
  int every = 5, threads = 0;
  bool no_level = false;
};

struct Pending {
  ScanRecord record;
  int frame = 0;
};

// The scans of `batch`, prepared (no calibration), deskewed by the trajectory and placed on it.
void add_batch(const std::vector<Pending>& batch, const Trajectory& traj, const std::vector<double>& stamps,
               const MappingConfig& config, const PipelineOptions& options, std::vector<CalibrationScan>& scans) {
  std::vector<CalibrationScan> out(batch.size());
  tbb::parallel_for(size_t{0}, batch.size(), [&](size_t k) {
    const int f = batch[k].frame;
    PreparedScan p;
    try {
      p = prepare_scan(batch[k].record.load(), batch[k].record.stamp, config.preprocess, options);
    } catch (const Error& e) {
      spdlog::warn("skipping scan {}: {}", f, e.what());
      return;
    }
    const int a = f + 1 < static_cast<int>(traj.poses.size()) ? f : f - 1;
    const double dt = a >= 0 ? stamps[a + 1] - stamps[a] : 0.0;
    const Vector6d velocity = dt > 1e-6 ? Vector6d(se3_log(traj.poses[a].inverse() * traj.poses[a + 1]) / dt) : Vector6d::Zero();
    out[k] = calibration_scan(std::move(*p.cloud), traj.poses[f], config.preprocess.deskew && dt > 1e-6 ? &velocity : nullptr);
  });
  for (CalibrationScan& s : out)
    if (!s.cloud.empty()) scans.push_back(std::move(s));
}

std::vector<CalibrationScan> read_scans(const CalibrateOptions& o, const Trajectory& traj, const MappingConfig& config) {
  Input input = open_input(o.input);
  PipelineOptions options;
  options.kitti_hdl64 = input.kitti_hdl64;
  // Stamps of every frame (the trajectory's frames), loads of every `every`-th.
  std::vector<double> stamps;
  std::vector<Pending> records;
  while (auto r = input.source->next()) {
    stamps.push_back(r->stamp);
    if ((stamps.size() - 1) % o.every == 0) records.push_back({std::move(*r), static_cast<int>(stamps.size() - 1)});
  }
  if (stamps.size() != traj.poses.size())
    throw Error(o.trajectory + ": " + std::to_string(traj.poses.size()) + " poses for " + std::to_string(stamps.size()) +
                " scans of " + o.input.input + " (give the same --start and --max-frames as the run)");
  std::vector<CalibrationScan> scans;
  Progress progress("scan", records.size(), o.input.quiet);
  constexpr size_t kBatch = 8;
  for (size_t first = 0; first < records.size(); first += kBatch) {
    const std::vector<Pending> batch(records.begin() + first, records.begin() + std::min(records.size(), first + kBatch));
    add_batch(batch, traj, stamps, config, options, scans);
    progress.update(scans.size());
  }
  progress.finish();
  return scans;
}

int calibrate(const CalibrateOptions& o) {
  const auto threads = limit_threads(o.threads);
  if (o.every < 1) throw Error("--every: must be >= 1");
  MappingConfig config = o.config_file.empty() ? MappingConfig{} : MappingConfig::load(o.config_file);
  const Trajectory traj = read_trajectory(o.trajectory);
  std::vector<CalibrationScan> scans = read_scans(o, traj, config);
  if (!o.no_level) level_with_walls(scans);
  std::fprintf(stderr, "Estimating from %zu scans...\n", scans.size());
  const ElevationCalibration c = ElevationCalibration::estimate(scans);
  const std::string text = c.to_text();
  write_file_atomic(o.output, [&](std::ostream& s) { s << text; });
  std::fprintf(stderr, "Wrote %s: elevation offsets for %d elevations (largest %.3f deg); map with --elevation-calibration %s\n",
               o.output.c_str(), c.num_offsets(), c.largest_offset() * 180.0 / M_PI, o.output.c_str());
  return 0;
}

}  // namespace

void add_calibrate(CLI::App& app, Runner& run) {
  auto o = std::make_shared<CalibrateOptions>();
  auto* cmd = app.add_subcommand("calibrate",
                                 "Per-beam elevation offsets of a spinning LiDAR from a recording and its mapped trajectory");
  cmd->add_option("input", o->input.input, "Sequence folder or bag (as given to gcmap map)")->required();
  cmd->add_option("--trajectory", o->trajectory, "The run's trajectory.kitti (one pose per scan)")->required();
  cmd->add_option("-o,--output", o->output, "Calibration file to write")->required();
  cmd->add_option("--every", o->every, "Use every N-th scan")->capture_default_str();
  cmd->add_option("--config", o->config_file, "YAML configuration of the run (preprocessing)");
  cmd->add_flag("--no-level", o->no_level,
                "Trust the trajectory's roll and pitch (a reference) instead of levelling it by vertical walls");
  cmd->add_option("--topic", o->input.topic, "Bags: the point-cloud topic (default: the only one)");
  cmd->add_option("--start", o->input.start, "First scan index")->capture_default_str();
  cmd->add_option("--max-frames", o->input.max_frames, "Process at most this many scans (0 = all)")->capture_default_str();
  cmd->add_option("--threads", o->threads, "Worker threads (0 = all cores)")->capture_default_str();
  cmd->add_flag("--quiet", o->input.quiet, "No progress line");
  cmd->callback([o, &run] { run = [o] { return calibrate(*o); }; });
}

}  // namespace gcmap::cli
