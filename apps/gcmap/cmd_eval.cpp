#include <iostream>

#include "commands.hpp"
#include "gcmap/core/error.hpp"
#include "gcmap/core/preprocess.hpp"
#include "gcmap/core/timer.hpp"
#include "gcmap/eval/map_entropy.hpp"
#include "gcmap/eval/trajectory_metrics.hpp"
#include "gcmap/io/json.hpp"
#include "gcmap/io/point_cloud_io.hpp"
#include "gcmap/io/sequence.hpp"
#include "gcmap/io/trajectory_io.hpp"
#include "progress.hpp"

namespace gcmap::cli {

namespace {

// A length without segments has no error: null, never 0 (which reads as a perfect score).
Json percent_or_null(double value, size_t count) { return count ? Json(value) : Json(); }

Json kitti_json(const KittiError& k) {
  Json kj = Json::object();
  kj["translation_percent"] = percent_or_null(k.translation_percent, k.num_segments);
  kj["rotation_deg_per_100m"] = percent_or_null(k.rotation_deg_per_100m, k.num_segments);
  kj["num_segments"] = k.num_segments;
  if (!k.num_segments) kj["note"] = "no segment of 100 m or more: the KITTI relative error is undefined";
  Json per = Json::array();
  for (const auto& s : k.per_length) {
    Json sj = Json::object();
    sj["length_m"] = s.length;
    sj["count"] = s.count;
    sj["translation_percent"] = percent_or_null(s.translation_percent, s.count);
    sj["rotation_deg_per_100m"] = percent_or_null(s.rotation_deg_per_100m, s.count);
    per.push_back(sj);
  }
  kj["per_length"] = per;
  return kj;
}

Json trajectory_report(const Poses& gt, const Poses& est, const KittiError& k) {
  const AbsoluteError a = absolute_trajectory_error(gt, est);
  const RelativePoseError r = relative_pose_error(gt, est);
  Json out = Json::object();
  out["kitti"] = kitti_json(k);
  Json aj = Json::object();
  aj["rmse"] = a.rmse;
  aj["mean"] = a.mean;
  aj["max"] = a.max;
  out["ate_m"] = aj;
  Json rj = Json::object();
  rj["translation_rmse_m"] = r.translation_rmse;
  rj["translation_mean_m"] = r.translation_mean;
  rj["translation_max_m"] = r.translation_max;
  rj["rotation_rmse_deg"] = r.rotation_rmse_deg;
  rj["rotation_mean_deg"] = r.rotation_mean_deg;
  rj["rotation_max_deg"] = r.rotation_max_deg;
  out["rpe"] = rj;
  return out;
}

}  // namespace

void add_eval(CLI::App& app, Runner& run) {
  struct Options {
    std::string gt, est, format, calib;
    bool vertical = false;
  };
  auto opt = std::make_shared<Options>();
  auto* cmd = app.add_subcommand("eval", "Compare a trajectory with ground truth: KITTI relative error, ATE, RPE (JSON)");
  cmd->add_option("--gt", opt->gt, "Ground-truth trajectory (KITTI or TUM)")->required();
  cmd->add_option("--est", opt->est, "Estimated trajectory (KITTI or TUM)")->required();
  cmd->add_option("--format", opt->format, "Force both files to be read as kitti or tum (default: detected)");
  cmd->add_option("--calib", opt->calib, "KITTI calib.txt: convert Velodyne-frame estimates into camera 0 with Tr");
  cmd->add_flag("--vertical", opt->vertical,
                "Also how far each pose's vertical is from the truth's (deg): for a --gt whose z is up (a simulation's "
                "poses_world.txt) and a run levelled by an IMU or GNSS");
  cmd->callback([opt, &run] {
    run = [opt] {
      const Trajectory gt = read_trajectory(opt->gt);
      Trajectory est = read_trajectory(opt->est);
      if (!opt->format.empty()) {
        const TrajectoryFormat f = parse_trajectory_format(opt->format);
        if (gt.format != f) throw Error(opt->gt + ": is not in " + opt->format + " format");
        if (est.format != f) throw Error(opt->est + ": is not in " + opt->format + " format");
      }
      if (!opt->calib.empty()) {
        const Eigen::Isometry3d Tr = read_kitti_calib_tr(opt->calib);
        for (auto& T : est.poses) T = Tr * T * Tr.inverse();
      }
      if (gt.size() != est.size())
        throw Error(opt->est + ": has " + std::to_string(est.size()) + " poses, " + opt->gt + " has " +
                    std::to_string(gt.size()));
      if (gt.size() < 2) throw Error(opt->gt + ": has 1 pose, eval needs at least 2");
      const KittiError k = kitti_relative_error(gt.poses, est.poses);
      if (!k.num_segments)
        std::cerr << opt->gt
                  << ": no segment of 100 m or more, the KITTI relative error is undefined (null); ATE and RPE apply\n";
      Json report = trajectory_report(gt.poses, est.poses, k);
      if (opt->vertical) {
        const VerticalError v = vertical_error(gt.poses, est.poses);
        Json vj = Json::object();
        vj["rmse"] = v.rmse_deg;
        vj["mean"] = v.mean_deg;
        vj["max"] = v.max_deg;
        report["vertical_deg"] = vj;
      }
      std::cout << report.dump() << std::endl;
      return 0;
    };
  });
}

void add_mme(CLI::App& app, Runner& run) {
  struct Options {
    std::string map, clouds, poses, bin_fields = "xyzi";
    double radius = 0.3, downsample = 0.0;
    int min_neighbors = 15, threads = 0;
    bool quiet = false;
  };
  auto opt = std::make_shared<Options>();
  auto* cmd = app.add_subcommand("mme", "Mean map entropy of a map (or of scans assembled with poses)");
  cmd->add_option("map", opt->map, "Map point cloud (.ply, .pcd, .bin)");
  cmd->add_option("--clouds", opt->clouds, "Instead of MAP: a folder of scans (KITTI layout or .bin/.pcd/.ply files)");
  cmd->add_option("--poses", opt->poses, "With --clouds: one pose per scan (KITTI or TUM)");
  cmd->add_option("--radius", opt->radius, "Neighbourhood radius in m")->capture_default_str();
  cmd->add_option("--min-neighbors", opt->min_neighbors, "Points with fewer neighbours are skipped")->capture_default_str();
  cmd->add_option("--downsample", opt->downsample, "With --clouds: voxel-downsample the assembled map (0 = off)")
      ->capture_default_str();
  cmd->add_option("--bin-fields", opt->bin_fields, "Layout of .bin files: xyzi or xyz")->capture_default_str();
  cmd->add_option("--threads", opt->threads, "Worker threads (0 = all cores)")->capture_default_str();
  cmd->add_flag("--quiet", opt->quiet, "No progress on stderr");
  cmd->callback([opt, &run] {
    run = [opt] {
      const auto threads = limit_threads(opt->threads);
      Stopwatch w;
      PointCloud map;
      if (!opt->clouds.empty()) {
        if (opt->poses.empty()) throw Error("--clouds needs --poses");
        const auto files = list_scan_files(opt->clouds);
        const Trajectory traj = read_trajectory(opt->poses);
        if (traj.size() != files.size())
          throw Error(opt->poses + ": has " + std::to_string(traj.size()) + " poses for " + std::to_string(files.size()) +
                      " scans");
        const BinFields fields = parse_bin_fields(opt->bin_fields);
        Progress reading("mme: scan", files.size(), opt->quiet);
        for (size_t k = 0; k < files.size(); ++k) {
          const PointCloud c = transformed(read_point_cloud(files[k], fields), traj.poses[k]);
          map.points.insert(map.points.end(), c.points.begin(), c.points.end());
          reading.update(k + 1, std::to_string(map.size()) + " points");
        }
        reading.finish();
        if (opt->downsample > 0) map = voxel_downsample(map, opt->downsample);
      } else {
        if (opt->map.empty()) throw Error("give a MAP file or --clouds DIR --poses POSES");
        map = read_point_cloud(opt->map, parse_bin_fields(opt->bin_fields));
      }
      Progress points("mme: point", map.size(), opt->quiet);
      const MapEntropy e =
          mean_map_entropy(map, opt->radius, opt->min_neighbors, [&](size_t done, size_t) { points.update(done); });
      points.finish();
      Json out = Json::object();
      out["mme"] = e.mean;
      out["stddev"] = e.stddev;
      out["num_points"] = map.size();
      out["num_evaluated"] = e.num_points;
      out["num_skipped"] = e.num_skipped;
      out["seconds"] = w.ms() / 1000.0;
      std::cout << out.dump() << std::endl;
      return 0;
    };
  });
}

}  // namespace gcmap::cli
