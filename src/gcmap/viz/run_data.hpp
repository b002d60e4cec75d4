#pragma once
// The outputs of `gcmap map` read back for the pictures: map.ply, trajectory.kitti, graph.json,
// stats.json. Every reader throws Error("PATH: ...") on a missing, truncated or malformed file.
#include <Eigen/Geometry>
#include <string>
#include <vector>

#include "gcmap/core/point_cloud.hpp"
#include "gcmap/eval/trajectory_metrics.hpp"
#include "gcmap/mapping/factor_kind.hpp"

namespace gcmap::viz {

struct GraphNode {
  int id = 0;
  int first_frame = 0;
  Eigen::Isometry3d T_out_submap = Eigen::Isometry3d::Identity();  // in the frame of trajectory.kitti (see below)
};
struct GraphEdge {
  FactorKind kind = FactorKind::matching_cost;
  int source = 0, target = 0;  // node indices
  double weight = 1.0;         // robust-kernel weight at the final estimate (1 for matching-cost factors)
};
struct RunGraph {
  std::vector<GraphNode> nodes;
  std::vector<GraphEdge> edges;
  bool has(FactorKind kind) const;
  size_t count(FactorKind kind) const;
};

// graph.json writes submap poses in the optimizer's world frame; trajectory.kitti and map.ply are
// expressed in the frame of the run's first frame. That frame is the first keyframe of submap 0,
// which sits at its submap's origin: read_graph_json returns the nodes relative to submap 0
// (T_out_submap = inverse(T_world_submap0) * T_world_submap), read_run then places them with the
// trajectory's first pose (the identity in `gcmap map` outputs).
RunGraph read_graph_json(const std::string& path);

struct ModuleTiming {
  std::string module;
  double mean_ms = 0.0, std_ms = 0.0, max_ms = 0.0;
  size_t count = 0;
};
struct InsertionStats {  // one global-graph insertion (a new submap)
  int submaps = 0, factors = 0, iterations = 0;
  double global_optimization_ms = 0.0;
};
struct RunStats {
  std::vector<ModuleTiming> timing;  // in the order of stats.json
  std::vector<InsertionStats> per_submap;
};
RunStats read_stats_json(const std::string& path);

struct RunData {
  PointCloud map;
  Poses trajectory;
  RunGraph graph;  // empty unless read
};

// A file a picture command wrote, and what it shows in words (for the command to print).
struct WrittenFile {
  std::string path;
  std::string what;
};

// DIR/NAME after checking that DIR is an existing folder.
std::string run_file(const std::string& dir, const std::string& name);

// map.ply and trajectory.kitti of a run folder, and graph.json when with_graph.
RunData read_run(const std::string& dir, bool with_graph);

}  // namespace gcmap::viz
