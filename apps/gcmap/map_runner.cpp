#include "map_runner.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <optional>

#include "gcmap/core/error.hpp"
#include "gcmap/core/memory.hpp"
#include "gcmap/core/timer.hpp"
#include "gcmap/cuda/cuda_backend.hpp"
#include "gcmap/io/bag_scans.hpp"
#include "gcmap/io/file.hpp"
#include "gcmap/io/gnss_io.hpp"
#include "gcmap/io/point_cloud_io.hpp"
#include "gcmap/io/sequence.hpp"
#include "gcmap/io/trajectory_io.hpp"
#include "gcmap/mapping/pipeline.hpp"
#include "gcmap/mapping/quality.hpp"
#include "gcmap/mapping/report.hpp"
#include "gcmap/mapping/self_calibration.hpp"
#include "gcmap/session/session.hpp"
#include "gcmap/viz/report_html.hpp"
#include "progress.hpp"

namespace gcmap::cli {

namespace fs = std::filesystem;

namespace {

// What the GPU holds at the end of the run: the submaps' clouds and voxel maps it keeps for the
// global factors, and the per-iteration buffers of the last batch.
Json device_memory_json(const cuda::CudaBackend& gpu, const MappingPipeline& pipeline) {
  const cuda::DeviceMemory m = gpu.memory();
  const size_t submaps = std::max<size_t>(pipeline.submaps().size(), 1), factors = std::max<size_t>(pipeline.factors().size(), 1);
  Json j = Json::object();
  j["clouds"] = m.num_clouds;
  j["cloud_mb"] = m.cloud_bytes / 1e6;
  j["voxel_maps"] = m.num_maps;
  j["voxel_map_mb"] = m.map_bytes / 1e6;
  j["batch_mb"] = m.batch_bytes / 1e6;
  j["mb_per_submap"] = (m.cloud_bytes + m.map_bytes) / 1e6 / submaps;
  j["mb_per_factor"] = m.batch_bytes / 1e6 / factors;
  return j;
}

// What the submaps hold on the host at the end of the run: the part of the memory that grows
// with the map (the rest is bounded by the window of the front end).
Json host_memory_json(const MappingPipeline& pipeline) {
  size_t clouds = 0, sources = 0, maps = 0;
  for (const Submap& s : pipeline.submaps()) {
    if (s.cloud) clouds += s.cloud->memory_bytes();
    if (s.factor_source) sources += s.factor_source->memory_bytes();
    if (s.voxels) maps += s.voxels->memory_bytes();
  }
  Json j = Json::object();
  j["submap_cloud_mb"] = clouds / 1e6;
  j["factor_source_mb"] = sources / 1e6;
  j["voxel_map_mb"] = maps / 1e6;
  j["mb_per_submap"] = (clouds + sources + maps) / 1e6 / std::max<size_t>(pipeline.submaps().size(), 1);
  return j;
}

void check_writable(const std::string& dir) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec || !fs::is_directory(dir)) throw Error(dir + ": cannot create output folder");
  const std::string probe = (fs::path(dir) / ".gcmap_write_test").string();
  std::ofstream f(probe);
  if (!f) throw Error(dir + ": output folder is not writable");
  f.close();
  fs::remove(probe, ec);
}

// Outputs in the input folder (or inside a KITTI input's scans folder) would be read back as scans.
void check_output_apart(const std::string& output, const InputAssumptions& input) {
  if (input.layout == InputLayout::bag) return;
  auto clean = [](const fs::path& p) {
    fs::path out = fs::weakly_canonical(fs::absolute(p));
    return out.filename().empty() ? out.parent_path() : out;
  };
  const fs::path out = clean(output), in = clean(input.input), scans = clean(input.scans_dir);
  const auto [end, rest] = std::mismatch(scans.begin(), scans.end(), out.begin(), out.end());
  if (out == in || end == scans.end())
    throw Error(output + ": the output folder is the input's scans folder or inside it; choose another -o");
}

// SIGINT/SIGTERM: the first stops reading scans (the run finishes what it has and writes partial
// outputs), a second skips the final optimization.
std::atomic<bool> g_stop{false};
std::atomic<int> g_signals{0}, g_last_signal{0};
extern "C" void on_signal(int sig) {
  g_last_signal = sig;
  g_stop = true;
  ++g_signals;
}

class SignalScope {
 public:
  SignalScope() {
    g_stop = false;
    g_signals = 0;
    g_last_signal = 0;
    struct sigaction sa {};
    sa.sa_handler = on_signal;
    sigemptyset(&sa.sa_mask);
    sigaction(SIGINT, &sa, &old_int_);
    sigaction(SIGTERM, &sa, &old_term_);
  }
  ~SignalScope() {
    sigaction(SIGINT, &old_int_, nullptr);
    sigaction(SIGTERM, &old_term_, nullptr);
  }

 private:
  struct sigaction old_int_ {};
  struct sigaction old_term_ {};
};

// The fixes in the local ENU frame at the first fix.
std::vector<GnssPosition> gnss_positions(const std::vector<GnssFix>& fixes) {
  std::vector<GnssPosition> out;
  for (const GnssFix& f : fixes) out.push_back({f.stamp, enu_from_geodetic(fixes.front().position, f.position), f.sigma_enu});
  return out;
}

Json gnss_json(const GnssStats& s, const InputAssumptions& a, int epsg) {
  Json j = Json::object();
  j["file"] = a.gnss_path;
  j["fixes"] = s.fixes;
  j["used"] = s.used;
  j["rejected"] = s.rejected;
  j["downweighted"] = s.downweighted;
  j["outside_scans"] = s.outside;
  j["in_gaps"] = s.gaps;
  j["waiting_for_alignment"] = s.waiting;
  j["rms_residual_m"] = s.rms_residual;
  j["georeferenced"] = s.georeferenced;
  const Geodetic& o = a.gnss_fixes.front().position;
  Json origin = Json::array();
  for (double v : {o.lat_deg, o.lon_deg, o.alt_m}) origin.push_back(v);
  j["enu_origin"] = origin;
  j["map_frame"] = s.georeferenced ? "local ENU at enu_origin (x east, y north, z up)" : "not georeferenced: see map_frame above";
  if (epsg) j["utm_epsg"] = epsg;
  return j;
}

std::string gnss_line(const GnssStats& s, int epsg) {
  char buf[320];
  std::snprintf(
      buf, sizeof buf,
      "GNSS: %zu fixes: %zu used (%zu rejected beyond the outlier threshold, rms residual of the rest %.3f m), %zu "
      "outside the scans, %zu in gaps; %s",
      s.fixes, s.used, s.rejected, s.rms_residual, s.outside, s.gaps,
      s.georeferenced
          ? ("map in local ENU; trajectory_utm.txt (EPSG:" + std::to_string(epsg) + ") and trajectory_wgs84.txt written").c_str()
          : "the fixes never spanned gnss.align_distance: NOT georeferenced");
  return buf;
}

// What the clock check says: agreement, or the offset to set.
std::string clock_verdict(const GyroTrack::ClockCheck& c, double configured) {
  // Enough turning to tell, a shift beyond the check's resolution, and clearly better rates there.
  const bool off = c.windows >= 20 && std::abs(c.best_shift) >= 0.005 && c.rms_at_zero > 1.2 * c.rms_at_best;
  if (!off) return fmt::format("its clock agrees with the LiDAR's at imu.time_offset {:.3f} s", configured);
  return fmt::format(
      "WARNING: its rates agree with the registration's best {:.0f} ms {} (rms {:.4f} against {:.4f} rad/s): set imu.time_offset "
      "to {:.3f} s and map again",
      std::abs(c.best_shift) * 1e3, c.best_shift > 0 ? "later" : "earlier", c.rms_at_best, c.rms_at_zero, configured + c.best_shift);
}

std::string imu_line(const PipelineStats& s, const ImuConfig& imu) {
  const double configured_offset = imu.time_offset, configured_noise = imu.noise.gyro_noise;
  const Eigen::Vector3d b = s.gyro_bias * 180.0 / M_PI;
  std::string line = fmt::format("IMU: {} samples; the gyro deskewed {} of {} sweeps; gyro bias estimate ({:.4f}, {:.4f}, {:.4f}) deg/s",
                                 s.imu_samples, s.gyro_deskewed, s.frames, b.x(), b.y(), b.z());
  if (s.gyro_rejected_at)
    return line + fmt::format(
                      "; WARNING: from frame {} on it was not used, its rates not following the LiDAR's rotation (rms {:.3f} "
                      "against rates of {:.3f} rad/s): check imu.roll_deg, pitch_deg and yaw_deg",
                      *s.gyro_rejected_at, s.imu_clock->rms_at_best, s.imu_clock->rms_rate);
  if (s.imu_clock) line += "; " + clock_verdict(*s.imu_clock, configured_offset);
  if (s.imu_clock && s.deskew_gyro_noise < configured_noise)
    line += fmt::format(
        "; its white noise, measured against the registration, {:.2e} rad/s/sqrt(Hz) (imu.gyro_noise {:.2e}): the "
        "deskewing weighs the gyro by the measured one",
        s.deskew_gyro_noise, configured_noise);
  line += fmt::format("; the LiDAR-inertial state predicted {} sweeps", s.inertial_predicted);
  if (s.inertial_deskewed > 0)
    line += fmt::format(" and deskewed {} with its motion (the registration's rates scattering over twice the gyro's noise)",
                        s.inertial_deskewed);
  if (s.inertial_bias) {
    const Eigen::Vector3d bg = s.inertial_bias->gyro * 180.0 / M_PI, ba = s.inertial_bias->accel;
    line += fmt::format(" (its biases at the end: gyro ({:.4f}, {:.4f}, {:.4f}) deg/s, accelerometer ({:.3f}, {:.3f}, {:.3f}) m/s^2",
                        bg.x(), bg.y(), bg.z(), ba.x(), ba.y(), ba.z());
    if (s.inertial_gravity_turn_deg)
      line += fmt::format("; its gravity {:.2f} deg from where its start found it, as the odometry's roll and pitch wandered",
                          *s.inertial_gravity_turn_deg);
    line += ")";
  }
  const GravityStats& g = s.gravity;
  if (g.levelled)
    line += fmt::format("; the map's z is gravity's ({} windows of the accelerometer, rms tilt {:.3f} deg, accelerometer bias "
                        "({:.3f}, {:.3f}, {:.3f}) m/s^2)",
                        g.windows, g.rms_tilt_deg, g.accel_bias.x(), g.accel_bias.y(), g.accel_bias.z());
  else
    line += "; the map is not levelled by gravity (imu.level_map off, or no window of the accelerometer)";
  return line;
}

// The UTM zone of the first fix; 0 without GNSS.
int gnss_epsg(const InputAssumptions& input) {
  return input.gnss_fixes.empty() ? 0 : utm_epsg(input.gnss_fixes.front().position);
}

void write_outputs(const MappingPipeline& pipeline, int frame_offset, const MapRunOptions& o, int signal,
                   const std::vector<std::string>& input_warnings, const InputAssumptions& input) {
  // The quality report, the map's assembly and the session can take a while on a long drive: a
  // line as each begins.
  Progress writing("writing outputs, step", o.config.output.pcd ? 7 : 6, o.quiet);
  writing.without_rate();
  size_t step = 0;
  const auto next = [&](const std::string& what) { writing.step(++step, what); };
  next("quality report");
  Stopwatch clock;
  const QualityReport quality = assess_quality(pipeline, o.config.quality, frame_offset);
  if (!o.quiet) {
    spdlog::info("quality report ({} submap pairs compared) in {:.1f} s:", quality.pairs.size(), clock.ms() / 1e3);
    for (const std::string& line : quality.verdict) spdlog::info("quality: {}", line);
  }
  write_folder_contents_atomic(o.output, [&](const std::string& staging) {
    const fs::path out(staging);
    next("trajectories");
    Trajectory traj;
    traj.poses = pipeline.trajectory();
    traj.stamps = pipeline.stamps();
    traj.format = TrajectoryFormat::kitti;
    write_trajectory((out / "trajectory.kitti").string(), traj);
    traj.format = TrajectoryFormat::tum;
    write_trajectory((out / "trajectory.tum").string(), traj);
    if (pipeline.mapper().georeferenced()) {
      const Geodetic& origin = input.gnss_fixes.front().position;
      write_trajectory_utm((out / "trajectory_utm.txt").string(), origin, gnss_epsg(input), traj.stamps, traj.poses);
      write_trajectory_wgs84((out / "trajectory_wgs84.txt").string(), origin, traj.stamps, traj.poses);
    }
    Trajectory odom;
    odom.poses = pipeline.odometry();
    write_trajectory((out / "odometry.kitti").string(), odom);
    next("assembling the map");
    const PointCloud map = pipeline.map(o.config.output.map_resolution);
    next("map.ply");
    write_ply((out / "map.ply").string(), map);
    if (o.config.output.pcd) next("map.pcd");
    if (o.config.output.pcd) write_pcd((out / "map.pcd").string(), map);
    next("graph.json, stats.json, config.yaml");
    const Json graph = graph_json(pipeline, frame_offset);
    write_file_atomic((out / "graph.json").string(), [&](std::ostream& s) { s << graph.dump() << "\n"; });
    Json stats = stats_json(pipeline);
    stats["peak_rss_mb"] = peak_rss_bytes() / 1e6;
    stats["partial"] = signal != 0;
    if (signal) stats["interrupted_by"] = signal == SIGINT ? "SIGINT" : "SIGTERM";
    Json warnings = Json::array();  // e.g. a truncated bag: mapped up to the damage
    for (const std::string& w : input_warnings) warnings.push_back(w);
    stats["input_warnings"] = warnings;
    stats["assumptions"] = input.to_json();
    if (!input.gnss_fixes.empty()) stats["gnss"] = gnss_json(pipeline.mapper().gnss_stats(), input, gnss_epsg(input));
    stats["host_memory"] = host_memory_json(pipeline);
    if (const auto* gpu = dynamic_cast<const cuda::CudaBackend*>(&pipeline.backend()))
      stats["device_memory"] = device_memory_json(*gpu, pipeline);
    write_file_atomic((out / "stats.json").string(), [&](std::ostream& s) { s << stats.dump() << "\n"; });
    write_file_atomic((out / "quality.json").string(), [&](std::ostream& s) { s << quality_json(quality).dump() << "\n"; });
    write_file_atomic((out / "report.html").string(), [&](std::ostream& s) { s << viz::report_html(quality, pipeline); });
    write_file_atomic((out / "config.yaml").string(), [&](std::ostream& s) { s << o.config.to_yaml(); });
    if (const ElevationCalibration* c = pipeline.elevation_calibration())
      write_file_atomic((out / "elevation_calibration.txt").string(), [&](std::ostream& s) { s << c->to_text(); });
    next("session/");
    write_session((out / "session").string(), pipeline, traj.stamps);
  });
  writing.finish();
}

std::string progress_detail(const MappingPipeline& p) {
  const auto& opt = p.mapper().global_stats().optimization.samples_ms;
  char buf[96];
  std::snprintf(buf, sizeof buf, "submaps %zu  factors %zu  last global opt %.0f ms", p.submaps().size(), p.factors().size(),
                opt.empty() ? 0.0 : opt.back());
  return buf;
}

std::string fmt_error(double e) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", e);
  return buf;
}

// error: of the last iteration; none before the first (or when there is nothing to optimize).
std::string final_detail(const MappingPipeline& p, std::optional<double> error) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "submaps %zu  factors %zu", p.submaps().size(), p.factors().size());
  return (error ? "error " + fmt_error(*error) + "  " : std::string()) + buf;
}

// Closes the last submap and runs the final optimization, a progress line per iteration; the last
// line gives the counts the summary and stats.json give.
void finish_with_progress(MappingPipeline& pipeline, std::optional<int> max_iterations, bool quiet) {
  const int total = max_iterations ? std::min(*max_iterations, pipeline.config().global.final_iterations)
                                   : pipeline.config().global.final_iterations;
  Progress progress("final optimization, iteration", static_cast<size_t>(std::max(total, 0)), quiet);
  progress.without_rate();
  int done = 0;
  std::optional<double> error;
  pipeline.finish(max_iterations, [&](const LMIteration& it) {
    done = it.iteration;
    error = it.error;
    progress.update(static_cast<size_t>(done), final_detail(pipeline, error));
  });
  progress.finish(static_cast<size_t>(done), final_detail(pipeline, error));
}

// The self-calibration's pass over the first frames, from a source of its own; states its outcome
// (assumptions.beam_calibration, a line).
std::shared_ptr<const ElevationCalibration> estimate_elevation(const MapRunOptions& o, bool kitti_hdl64,
                                                               InputAssumptions& assumptions) {
  MapRunOptions first = o;
  first.max_frames = o.max_frames > 0 ? std::min(o.max_frames, o.config.calibration.frames) : o.config.calibration.frames;
  const auto open = [&first] { return open_input(first).source; };
  // The run reads every scan again and reports what is wrong with them: here only the progress.
  std::optional<QuietWarnings> quiet(std::in_place);
  const size_t frames = open()->size_hint();
  Progress progress("beam elevation estimate, frame", frames * o.config.calibration.passes, o.quiet);
  SelfCalibration c;
  {
    SignalScope signals;
    c = self_calibrate_elevation(open, o.config, PipelineOptions{.kitti_hdl64 = kitti_hdl64, .elevation_calibration = nullptr},
                                 [&](int f) { progress.update(f + 1); }, &g_stop);
  }
  progress.finish();
  quiet.reset();
  if (g_stop) return nullptr;
  assumptions.beam_calibration = {c.calibration ? "estimated" : "none", c.summary};
  if (!o.quiet) spdlog::info("beam calibration: {}", c.summary);
  return c.calibration;
}

MapRunResult interrupted_before_mapping() {
  MapRunResult r;
  r.signal = g_last_signal;
  r.nothing_written = true;
  return r;
}

}  // namespace

Input open_input(const MapRunOptions& o) {
  if (o.start < 0) throw Error("--start: must be >= 0");
  if (o.max_frames < 0) throw Error("--max-frames: must be >= 0");
  const PreprocessConfig& pc = o.config.preprocess;
  const InputOptions io{.times_file = o.times_file,
                        .bin_fields = o.bin_fields,
                        .topic = o.topic,
                        .kitti_vertical_correction = pc.kitti_vertical_correction,
                        .deskew = pc.deskew,
                        .deskew_from_azimuth = pc.deskew_from_azimuth,
                        .elevation_calibration = pc.elevation_calibration,
                        .estimate_elevation_frames = o.config.calibration.estimate_elevation ? o.config.calibration.frames : 0,
                        .gnss_file = o.gnss_file,
                        .gnss_topic = o.gnss_topic,
                        .use_imu = o.config.imu.use,
                        .imu_levels_map = o.config.imu.level_map,
                        .imu_inertial_odometry = o.config.imu.inertial_odometry,
                        .imu_file = o.imu_file,
                        .imu_topic = o.imu_topic};
  if (is_bag_path(o.input)) {
    if (o.start_time < 0 || o.duration < 0) throw Error("--start-time and --duration must be >= 0");
    if (!o.times_file.empty()) throw Error("--times applies to folders of scans, not to the bag " + o.input);
    BagScanOptions bo;
    bo.topic = o.topic;
    bo.start_time = o.start_time;
    if (o.duration > 0) bo.duration = o.duration;
    InputAssumptions a = decide_input(o.input, io);
    return {std::make_unique<BagScanRecords>(o.input, bo, o.start, o.max_frames), false, o.start, std::move(a)};
  }
  if (!o.topic.empty() || o.start_time != 0 || o.duration != 0)
    throw Error("--topic, --start-time and --duration apply to bags, not to " + o.input);
  InputAssumptions a = decide_input(o.input, io);
  auto folder = std::make_unique<FolderScanSource>(a, o.start, o.max_frames, o.bin_fields);
  const bool kitti = folder->kitti_hdl64();
  return {std::move(folder), kitti, o.start, std::move(a)};
}

MapRunResult run_mapping(const MapRunOptions& o) {
  o.config.validate();
  Input input = open_input(o);
  ScanSource& source = *input.source;
  check_output_apart(o.output, input.assumptions);
  check_writable(o.output);
  // --quiet keeps the warnings; stats.json has every line.
  for (const std::string& line : input.assumptions.lines())
    if (line.rfind("warning: ", 0) == 0) spdlog::warn("{}", line.substr(9));
    else if (!o.quiet) spdlog::info("{}", line);
  Trajectory initial;
  if (!o.initial_trajectory.empty()) {
    initial = read_trajectory(o.initial_trajectory);
    const size_t need = source.size_hint() + o.start;
    if (initial.size() < need)
      throw Error(o.initial_trajectory + ": has " + std::to_string(initial.size()) + " poses, need " + std::to_string(need));
  }

  PipelineOptions po;
  po.kitti_hdl64 = input.kitti_hdl64;
  if (o.config.calibration.estimate_elevation && o.config.preprocess.elevation_calibration.empty()) {
    po.elevation_calibration = estimate_elevation(o, input.kitti_hdl64, input.assumptions);
    if (g_stop) return interrupted_before_mapping();
  }
  MappingPipeline pipeline(o.config, cuda::make_backend(o.device), po);
  if (!input.assumptions.gnss_fixes.empty()) pipeline.set_gnss(gnss_positions(input.assumptions.gnss_fixes));
  for (const ImuSample& sample : input.assumptions.imu_samples) pipeline.add_imu(sample);
  Progress progress("frame", source.size_hint(), o.quiet);
  MappingPipeline::RunOptions ro;
  if (!o.initial_trajectory.empty())
    ro.initial_pose = [&](int f) { return initial.poses[o.start].inverse() * initial.poses[f + o.start]; };
  ro.on_frame = [&](const Frame& f) { progress.update(f.index + 1, progress_detail(pipeline)); };
  ro.stop = &g_stop;
  int signal = 0;
  {
    SignalScope signals;
    pipeline.run(source, ro);
    progress.finish();
    if (g_stop) {
      signal = g_last_signal;
      spdlog::warn("interrupted after {} frames: closing the open submap, {} final optimization, writing partial outputs",
                   pipeline.num_frames(), g_signals > 1 ? "no" : "a bounded");
    }
    finish_with_progress(pipeline, signal ? std::optional<int>(g_signals > 1 ? 0 : 5) : std::nullopt, o.quiet);
  }
  const size_t unusable = pipeline.stats().unusable, frames = pipeline.num_frames();
  if (!signal && unusable == frames)
    throw Error(o.input + ": none of its " + std::to_string(frames) +
                " scans could be mapped (unreadable, empty or too few points: see the warnings above); nothing written");
  write_outputs(pipeline, input.frame_offset, o, signal, source.warnings(), input.assumptions);

  MapRunResult r;
  r.frames = pipeline.num_frames();
  r.submaps = pipeline.submaps().size();
  r.factors = pipeline.factors().size();
  r.seconds = pipeline.stats().seconds;
  r.fps = r.seconds > 0 ? r.frames / r.seconds : 0.0;
  r.signal = signal;
  r.elevation_calibration = pipeline.elevation_calibration() != nullptr;
  if (!input.assumptions.gnss_fixes.empty()) r.gnss = gnss_line(pipeline.mapper().gnss_stats(), gnss_epsg(input.assumptions));
  if (!input.assumptions.imu_samples.empty()) r.imu = imu_line(pipeline.stats(), o.config.imu);
  if (!signal && 2 * unusable > frames)
    r.failure = o.input + ": " + std::to_string(unusable) + " of its " + std::to_string(frames) +
                " scans could not be mapped (unreadable, empty or too few points: see the warnings above)";
  return r;
}

}  // namespace gcmap::cli
