#include <iostream>

#include "commands.hpp"
#include "gcmap/core/error.hpp"
#include "gcmap/core/gaussian_voxel_map.hpp"
#include "gcmap/core/preprocess.hpp"
#include "gcmap/core/timer.hpp"
#include "gcmap/cuda/cuda_backend.hpp"
#include "gcmap/graph/matching_graph.hpp"
#include "gcmap/io/json.hpp"
#include "gcmap/io/point_cloud_io.hpp"
#include "gcmap/registration/registration.hpp"
#include "gcmap/registration/vgicp.hpp"

namespace gcmap::cli {

namespace {
struct RegisterOptions {
  std::string target, source, init, bin_fields = "xyzi";
  double downsample = 0.25, voxel = 1.0;
  int threads = 0, max_iterations = 64;
  std::string device = "auto";
};
Json matrix_json(const Eigen::Isometry3d& T) {
  Json rows = Json::array();
  for (int i = 0; i < 4; ++i) {
    Json row = Json::array();
    for (int j = 0; j < 4; ++j) row.push_back(T.matrix()(i, j));
    rows.push_back(row);
  }
  return rows;
}
}  // namespace

void add_register(CLI::App& app, Runner& run) {
  auto opt = std::make_shared<RegisterOptions>();
  auto* cmd = app.add_subcommand("register", "Align SOURCE to TARGET with VGICP and print T_target_source as JSON");
  cmd->add_option("target", opt->target, "Target point cloud (.bin, .pcd, .ply)")->required();
  cmd->add_option("source", opt->source, "Source point cloud (.bin, .pcd, .ply)")->required();
  cmd->add_option("--init", opt->init, "Initial T_target_source as \"x y z qx qy qz qw\" (default identity)");
  cmd->add_option("--downsample", opt->downsample, "Voxel downsampling resolution in m (0 = off)")->capture_default_str();
  cmd->add_option("--voxel", opt->voxel, "VGICP voxel resolution in m")->capture_default_str();
  cmd->add_option("--max-iterations", opt->max_iterations, "LM iteration limit")->capture_default_str();
  cmd->add_option("--threads", opt->threads, "Worker threads (0 = all cores)")->capture_default_str();
  cmd->add_option("--bin-fields", opt->bin_fields, "Layout of .bin files: xyzi (KITTI) or xyz")->capture_default_str();
  cmd->add_option("--device", opt->device, "cpu, cuda or auto (a GPU when one answers)")->capture_default_str();
  cmd->footer("Exit code: 0 converged, 1 not converged, 2 bad input.");
  cmd->callback([opt, &run] {
    run = [opt] {
      const RegisterOptions& o = *opt;
      if (!(o.voxel > 0)) throw Error("--voxel: must be positive");
      if (o.downsample < 0) throw Error("--downsample: must be >= 0");
      if (o.max_iterations < 1) throw Error("--max-iterations: must be >= 1");
      const auto threads = limit_threads(o.threads);
      const BinFields fields = parse_bin_fields(o.bin_fields);
      const Eigen::Isometry3d init = o.init.empty() ? Eigen::Isometry3d::Identity() : parse_pose_option("--init", o.init);

      Stopwatch total, watch;
      PointCloud target = read_point_cloud(o.target, fields);
      PointCloud source = read_point_cloud(o.source, fields);
      if (target.size() < 10) throw Error(o.target + ": too few points (" + std::to_string(target.size()) + ")");
      if (source.size() < 10) throw Error(o.source + ": too few points (" + std::to_string(source.size()) + ")");
      const std::shared_ptr<LinearizationBackend> backend =
          cuda::make_backend(parse_device(o.device, "--device"));  // outside the timings
      watch.restart();
      if (o.downsample > 0) {
        target = voxel_downsample(target, o.downsample);
        source = voxel_downsample(source, o.downsample);
      }
      estimate_covariances(target);
      estimate_covariances(source);
      const double t_pre = watch.lap_ms();
      auto voxel_map = std::make_shared<GaussianVoxelMap>(o.voxel);
      voxel_map->insert(target);
      voxel_map->finalize();
      const GaussianVoxelMap& voxels = *voxel_map;
      const double t_vox = watch.lap_ms();
      RegistrationConfig config;
      config.max_iterations = o.max_iterations;
      const RegistrationResult r = backend->align(source, voxel_map, init, config);
      const double t_align = watch.lap_ms();

      Json out = Json::object();
      out["T_target_source"] = matrix_json(r.T_target_source);
      out["converged"] = r.converged;
      out["iterations"] = r.iterations;
      out["num_inliers"] = r.num_inliers;
      out["overlap"] = overlap(source, voxels, r.T_target_source);
      out["error"] = r.error;
      Json times = Json::object();
      times["preprocess"] = t_pre;
      times["voxelmap"] = t_vox;
      times["align"] = t_align;
      times["total"] = total.ms();
      out["time_ms"] = times;
      std::cout << out.dump() << std::endl;
      return r.converged ? 0 : 1;
    };
  });
}

}  // namespace gcmap::cli
