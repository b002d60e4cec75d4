#include "map_runner.hpp"

#include "commands.hpp"

#include <spdlog/spdlog.h>
#include <tbb/parallel_pipeline.h>
#include <unistd.h>

#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>

#include "gcmap/cuda/cuda_backend.hpp"
#include "gcmap/core/error.hpp"
#include "gcmap/mapping/preprocess_scan.hpp"
#include "gcmap/core/timer.hpp"
#include "gcmap/io/file.hpp"
#include "gcmap/io/point_cloud_io.hpp"
#include "gcmap/io/sequence.hpp"
#include "gcmap/io/trajectory_io.hpp"
#include "gcmap/mapping/mapper.hpp"
#include "gcmap/mapping/odometry.hpp"

namespace gcmap::cli {

namespace fs = std::filesystem;

namespace {

// KITTI's HDL-64 scans need a 0.22 deg intrinsic elevation correction (as in CT-ICP/KISS-ICP).
void kitti_vertical_correction(PointCloud& c) {
  const double angle = 0.22 * M_PI / 180.0;
  for (auto& p : c.points) {
    const Eigen::Vector3d v = p.cast<double>();
    const Eigen::Vector3d axis = v.cross(Eigen::Vector3d::UnitZ());
    if (axis.norm() < 1e-9) continue;
    p = (Eigen::AngleAxisd(angle, axis.normalized()) * v).cast<float>();
  }
}

// SemanticKITTI moving classes (252-259) are dropped when labels/NNNNNN.label exists.
void remove_dynamic(PointCloud& c, const std::string& label_path) {
  std::error_code ec;
  if (!fs::exists(label_path, ec)) return;
  const std::string bytes = read_file(label_path);
  if (bytes.size() != c.size() * 4) {
    spdlog::warn("{}: {} labels for {} points, ignored", label_path, bytes.size() / 4, c.size());
    return;
  }
  std::vector<char> keep(c.size());
  for (size_t i = 0; i < c.size(); ++i) {
    uint32_t l;
    std::memcpy(&l, bytes.data() + 4 * i, 4);
    const uint32_t cls = l & 0xffff;
    keep[i] = !(cls >= 252 && cls <= 259);
  }
  c.filter(keep);
}

Json timing_json(const TimingStats& t) {
  Json j = Json::object();
  j["mean_ms"] = t.mean();
  j["std_ms"] = t.stddev();
  j["max_ms"] = t.max();
  j["count"] = t.samples_ms.size();
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

}  // namespace

MapRunResult run_mapping(const MapRunOptions& o) {
  const MappingConfig& cfg = o.config;
  cfg.validate();
  if (o.start < 0) throw Error("--start: must be >= 0");
  if (o.max_frames < 0) throw Error("--max-frames: must be >= 0");
  std::vector<std::string> files = list_scan_files(o.input);
  if (o.start >= static_cast<int>(files.size()))
    throw Error("--start " + std::to_string(o.start) + ": the sequence has " + std::to_string(files.size()) + " scans");
  files.erase(files.begin(), files.begin() + o.start);
  if (o.max_frames > 0 && static_cast<int>(files.size()) > o.max_frames) files.resize(o.max_frames);
  check_writable(o.output);

  Trajectory initial;
  if (!o.initial_trajectory.empty()) {
    initial = read_trajectory(o.initial_trajectory);
    if (initial.size() < files.size() + o.start)
      throw Error(o.initial_trajectory + ": has " + std::to_string(initial.size()) + " poses, need " + std::to_string(files.size() + o.start));
  }
  const bool kitti = is_kitti_layout(o.input);
  // Our simulator writes the KITTI layout too, without the HDL-64's elevation error.
  const bool simulated = fs::exists(fs::path(o.input) / "scenario.json");
  const bool vertical = cfg.preprocess.kitti_vertical_correction && kitti && !simulated;
  const fs::path labels_dir = fs::path(o.input) / "labels";
  const bool with_labels = cfg.preprocess.remove_dynamic_labels && fs::is_directory(labels_dir);
  const bool progress = !o.quiet && isatty(2);

  Odometry odometry(cfg.odometry);
  const std::shared_ptr<LinearizationBackend> backend = cuda::make_backend(o.device);
  Mapper mapper(cfg, backend);
  std::vector<Eigen::Isometry3d> odom_poses;
  TimingStats t_pre, t_odom;
  Stopwatch total;
  size_t skipped = 0;
  // Scans are read and preprocessed ahead (up to 3 in flight, in parallel with the mapping of
  // earlier frames), then fed to odometry and mapping in order. The mapping stage alone cannot keep
  // both cores busy: its LM solve, assembly and voxel-map inserts are serial.
  struct Scan {
    size_t frame = 0;
    std::shared_ptr<PointCloud> cloud;  // null: unreadable
    std::string error;
    double preprocess_ms = 0.0;
  };
  size_t next = 0;
  tbb::parallel_pipeline(
      3,
      tbb::make_filter<void, Scan>(tbb::filter_mode::serial_in_order,
                                   [&](tbb::flow_control& fc) {
                                     Scan scan;
                                     if (next == files.size()) fc.stop();
                                     else scan.frame = next++;
                                     return scan;
                                   }) &
          tbb::make_filter<Scan, Scan>(tbb::filter_mode::parallel,
                                       [&](Scan scan) {
                                         Stopwatch w;
                                         try {
                                           const std::string& file = files[scan.frame];
                                           PointCloud raw = read_point_cloud(file);
                                           if (with_labels)
                                             remove_dynamic(raw, (labels_dir / (fs::path(file).stem().string() + ".label")).string());
                                           if (vertical) kitti_vertical_correction(raw);
                                           scan.cloud = std::make_shared<PointCloud>(preprocess_scan(raw, cfg.preprocess));
                                         } catch (const Error& e) {
                                           scan.error = e.what();
                                         }
                                         scan.preprocess_ms = w.ms();
                                         return scan;
                                       }) &
          tbb::make_filter<Scan, void>(tbb::filter_mode::serial_in_order, [&](const Scan& scan) {
            const size_t f = scan.frame;
            const std::shared_ptr<PointCloud>& cloud = scan.cloud;
            if (!cloud) {
              spdlog::warn("skipping scan: {}", scan.error);
              ++skipped;
            }
            t_pre.add(scan.preprocess_ms);
            Stopwatch w;
            Eigen::Isometry3d T;
            if (!o.initial_trajectory.empty()) {
              T = initial.poses[o.start].inverse() * initial.poses[f + o.start];
              odometry.set_pose(T);
            } else if (cloud) {
              T = odometry.track(cloud);
            } else {
              T = odometry.predict();
              odometry.set_pose(T);
            }
            t_odom.add(w.lap_ms());
            odom_poses.push_back(T);
            mapper.add_frame(static_cast<int>(f), cloud, T);
            if (progress && (f % 5 == 0 || f + 1 == files.size())) {
              std::fprintf(stderr, "\rframe %zu/%zu  %.1f frames/s  submaps %zu  factors %zu  last global opt %.0f ms   ", f + 1,
                           files.size(), (f + 1) / (total.ms() / 1000.0), mapper.submaps().size(), mapper.num_global_factors(),
                           mapper.stats().global_optimization.samples_ms.empty() ? 0.0 : mapper.stats().global_optimization.samples_ms.back());
            }
          }));
  mapper.finish();
  if (progress) std::fprintf(stderr, "\n");
  const double seconds = total.ms() / 1000.0;

  // Outputs, each written atomically.
  const std::vector<Eigen::Isometry3d> traj = mapper.trajectory();
  std::vector<double> stamps;
  {
    std::ifstream in(fs::path(o.input) / "times.txt");
    double t;
    while (in >> t) stamps.push_back(t);
  }
  Trajectory out;
  out.poses = traj;
  for (size_t f = 0; f < traj.size(); ++f) out.stamps.push_back(f + o.start < stamps.size() ? stamps[f + o.start] : 0.1 * (f + o.start));
  out.format = TrajectoryFormat::kitti;
  write_trajectory((fs::path(o.output) / "trajectory.kitti").string(), out);
  out.format = TrajectoryFormat::tum;
  write_trajectory((fs::path(o.output) / "trajectory.tum").string(), out);
  Trajectory odom;
  odom.poses = odom_poses;
  write_trajectory((fs::path(o.output) / "odometry.kitti").string(), odom);
  const PointCloud map = mapper.assemble_map(cfg.output.map_resolution);
  write_ply((fs::path(o.output) / "map.ply").string(), map);
  if (cfg.output.pcd) write_pcd((fs::path(o.output) / "map.pcd").string(), map);

  Json graph = Json::object();
  Json submaps = Json::array();
  for (const Submap& s : mapper.submaps()) {
    Json j = Json::object();
    j["id"] = s.id;
    j["pose"] = pose_json(mapper.submap_pose(s.id));
    j["first_frame"] = s.keyframes.front() + o.start;
    j["last_frame"] = s.keyframes.back() + o.start;
    j["keyframes"] = s.keyframes.size();
    j["points"] = s.cloud->size();
    submaps.push_back(j);
  }
  graph["submaps"] = submaps;
  Json factors = Json::array();
  for (const FactorInfo& fi : mapper.factors()) {
    Json j = Json::object();
    j["type"] = fi.type;
    j["source"] = fi.source;
    j["target"] = fi.target;
    j["overlap"] = fi.overlap;
    j["final_error"] = fi.error;
    if (fi.type != "matching_cost") j["final_weight"] = fi.weight;
    j["explicit_loop"] = fi.type == "loop";
    factors.push_back(j);
  }
  graph["factors"] = factors;
  Json loops = Json::array();  // every verified candidate, accepted or not
  for (const LoopRecord& l : mapper.loops()) {
    Json j = Json::object();
    j["source"] = l.source;
    j["target"] = l.target;
    j["descriptor_distance"] = l.descriptor_distance;
    j["inlier_fraction"] = l.inlier_fraction;
    j["inlier_rmse"] = l.inlier_rmse;
    j["accepted"] = l.accepted;
    loops.push_back(j);
  }
  graph["loop_candidates"] = loops;
  write_file_atomic((fs::path(o.output) / "graph.json").string(), [&](std::ostream& s) { s << graph.dump() << "\n"; });

  const MapperStats& ms = mapper.stats();
  Json stats = Json::object();
  stats["frames"] = files.size();
  stats["skipped_scans"] = skipped;
  stats["seconds"] = seconds;
  stats["frames_per_second"] = files.size() / seconds;
  const auto* gpu = dynamic_cast<const cuda::CudaBackend*>(backend.get());
  stats["device"] = gpu ? "cuda: " + gpu->device_name() : std::string("cpu");
  Json timing = Json::object();
  timing["preprocess"] = timing_json(t_pre);
  timing["odometry"] = timing_json(t_odom);
  timing["local_factor_creation"] = timing_json(ms.local_factors);
  timing["local_optimization"] = timing_json(ms.local_optimization);
  timing["global_factor_creation"] = timing_json(ms.global_factors);
  timing["global_optimization"] = timing_json(ms.global_optimization);
  timing["loop_detection"] = timing_json(ms.loop_detection);
  timing["loop_verification"] = timing_json(ms.loop_verification);
  stats["timing"] = timing;
  Json per = Json::array();
  for (const auto& p : ms.per_submap) {
    Json j = Json::object();
    j["submaps"] = p.num_submaps;
    j["factors"] = p.num_factors;
    j["global_optimization_ms"] = p.global_optimization_ms;
    j["global_iterations"] = p.global_iterations;
    per.push_back(j);
  }
  stats["per_submap"] = per;
  stats["final_optimization_ms"] = ms.final_optimization_ms;
  stats["final_iterations"] = ms.final_iterations;
  write_file_atomic((fs::path(o.output) / "stats.json").string(), [&](std::ostream& s) { s << stats.dump() << "\n"; });
  write_file_atomic((fs::path(o.output) / "config.yaml").string(), [&](std::ostream& s) { s << cfg.to_yaml(); });

  MapRunResult r;
  r.frames = files.size();
  r.submaps = mapper.submaps().size();
  r.factors = mapper.num_global_factors();
  r.seconds = seconds;
  r.fps = files.size() / seconds;
  r.stats = stats;
  return r;
}

}  // namespace gcmap::cli
