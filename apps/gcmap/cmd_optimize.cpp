#include <iostream>

#include "commands.hpp"
#include "gcmap/core/error.hpp"
#include "gcmap/core/preprocess.hpp"
#include "gcmap/cuda/cuda_backend.hpp"
#include "gcmap/graph/levenberg_marquardt.hpp"
#include "gcmap/graph/matching_graph.hpp"
#include "gcmap/io/json.hpp"
#include "gcmap/io/point_cloud_io.hpp"
#include "gcmap/io/trajectory_io.hpp"

namespace gcmap::cli {

namespace {
struct OptimizeOptions {
  std::string poses, out, bin_fields = "xyzi";
  std::vector<std::string> clouds;
  double min_overlap = 0.025, voxel = 1.0, downsample = 0.0;
  int max_iterations = 50, threads = 0;
  std::string device = "auto";
};
}  // namespace

void add_optimize(CLI::App& app, Runner& run) {
  auto opt = std::make_shared<OptimizeOptions>();
  auto* cmd = app.add_subcommand("optimize", "Jointly align clouds with VGICP matching-cost factors (multi-scan registration)");
  cmd->add_option("--poses", opt->poses, "Initial pose per cloud: 'vN x y z qx qy qz qw' or TUM lines")->required();
  cmd->add_option("--clouds", opt->clouds, "Point clouds, one per pose, in order")->required();
  cmd->add_option("--out", opt->out, "Write the optimized poses here, in the input format");
  cmd->add_option("--min-overlap", opt->min_overlap, "Create a factor for pairs with at least this voxel overlap")
      ->capture_default_str();
  cmd->add_option("--voxel", opt->voxel, "VGICP voxel resolution in m")->capture_default_str();
  cmd->add_option("--downsample", opt->downsample, "Voxel downsampling of the input clouds in m (0 = off)")
      ->capture_default_str();
  cmd->add_option("--bin-fields", opt->bin_fields, "Layout of .bin files: xyzi (KITTI) or xyz")->capture_default_str();
  cmd->add_option("--max-iterations", opt->max_iterations, "LM iteration limit")->capture_default_str();
  cmd->add_option("--threads", opt->threads, "Worker threads (0 = all cores)")->capture_default_str();
  cmd->add_option("--device", opt->device, "cpu, cuda or auto (a GPU when one answers)")->capture_default_str();
  cmd->footer("The first pose is held fixed. Prints one JSON object; exit code 2 on bad input.");
  cmd->callback([opt, &run] {
    run = [opt] {
      const OptimizeOptions& o = *opt;
      if (!(o.voxel > 0)) throw Error("--voxel: must be positive");
      if (o.min_overlap < 0 || o.min_overlap > 1) throw Error("--min-overlap: must be in [0, 1]");
      if (o.max_iterations < 1) throw Error("--max-iterations: must be >= 1");
      if (o.downsample < 0) throw Error("--downsample: must be >= 0");
      const auto threads = limit_threads(o.threads);
      const BinFields fields = parse_bin_fields(o.bin_fields);
      Trajectory traj = read_trajectory(o.poses);
      if (traj.format == TrajectoryFormat::kitti) throw Error(o.poses + ": expected 'vN x y z qx qy qz qw' or TUM lines");
      if (traj.size() != o.clouds.size())
        throw Error(o.poses + ": has " + std::to_string(traj.size()) + " poses but " + std::to_string(o.clouds.size()) +
                    " clouds were given");

      std::vector<ScanNode> nodes(o.clouds.size());
      Values values;
      for (size_t k = 0; k < o.clouds.size(); ++k) {
        PointCloud c = read_point_cloud(o.clouds[k], fields);
        if (o.downsample > 0) c = voxel_downsample(c, o.downsample);
        if (c.size() < 10) throw Error(o.clouds[k] + ": too few points (" + std::to_string(c.size()) + ")");
        nodes[k] = make_scan_node(std::move(c), o.voxel);
        values[static_cast<int>(k)] = traj.poses[k];
      }
      const std::shared_ptr<LinearizationBackend> backend = cuda::make_backend(parse_device(o.device, "--device"));
      FactorGraph graph;
      add_overlapping_pairs(graph, nodes, values, o.min_overlap, backend.get());
      LMConfig config;
      config.max_iterations = o.max_iterations;
      LevenbergMarquardt lm(config, backend);
      const LMResult r = lm.optimize(graph, values, {0});

      for (size_t k = 0; k < traj.size(); ++k) traj.poses[k] = values.at(static_cast<int>(k));
      if (!o.out.empty()) write_trajectory(o.out, traj);
      Json out = Json::object();
      out["num_factors"] = graph.factors.size();
      out["iterations"] = r.iterations;
      out["initial_error"] = r.initial_error;
      out["final_error"] = r.final_error;
      Json t = Json::object();
      t["linearize"] = r.linearize_ms;
      t["solve"] = r.solve_ms;
      t["total"] = r.total_ms;
      out["time_ms"] = t;
      Json poses = Json::array();
      for (const auto& T : traj.poses) poses.push_back(pose_json(T));
      out["poses"] = poses;
      std::cout << out.dump() << std::endl;
      return 0;
    };
  });
}

}  // namespace gcmap::cli
