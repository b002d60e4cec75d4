#include "gcmap/viz/run_data.hpp"

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <filesystem>

#include "gcmap/core/error.hpp"
#include "gcmap/core/se3.hpp"
#include "gcmap/io/file.hpp"
#include "gcmap/io/point_cloud_io.hpp"
#include "gcmap/io/trajectory_io.hpp"

namespace gcmap::viz {

namespace {

// JSON is a subset of YAML 1.2: yaml-cpp (already a dependency) parses it.
YAML::Node load_json_object(const std::string& path) {
  const std::string text = read_file(path);
  if (text.find_first_not_of(" \t\r\n") == std::string::npos) throw Error(path + ": empty file");
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::Exception& e) { throw Error(path + ": not valid JSON (" + e.msg + "; truncated?)"); }
  if (!root.IsMap()) throw Error(path + ": expected a JSON object");
  return root;
}

// Member `key` of object `node`; `where` names it in errors ("PATH: submaps[3]").
YAML::Node member(const YAML::Node& node, const char* key, const std::string& where) {
  if (!node.IsMap()) throw Error(where + ": expected an object");
  const YAML::Node v = node[key];
  if (!v) throw Error(where + ": missing \"" + key + "\"");
  return v;
}

YAML::Node array_member(const YAML::Node& node, const char* key, const std::string& where) {
  const YAML::Node v = member(node, key, where);
  if (!v.IsSequence()) throw Error(where + ": \"" + key + "\" is not an array");
  return v;
}

double number(const YAML::Node& node, const char* key, const std::string& where) {
  const YAML::Node v = member(node, key, where);
  double x = NAN;
  try {
    x = v.as<double>();
  } catch (const YAML::Exception&) {}
  if (!std::isfinite(x)) throw Error(where + ": \"" + key + "\" is not a finite number");
  return x;
}

int integer(const YAML::Node& node, const char* key, const std::string& where) {
  const double x = number(node, key, where);
  if (x != std::floor(x) || std::abs(x) > 2e9) throw Error(where + ": \"" + key + "\" is not an integer");
  return static_cast<int>(x);
}

std::string item(const std::string& path, const char* array, size_t i) {
  return path + ": " + array + "[" + std::to_string(i) + "]";
}

Eigen::Isometry3d pose(const YAML::Node& node, const std::string& where) {
  const YAML::Node p = member(node, "pose", where);
  if (!p.IsSequence() || p.size() != 7) throw Error(where + ": \"pose\" is not [x, y, z, qx, qy, qz, qw]");
  double v[7];
  for (size_t k = 0; k < 7; ++k) {
    v[k] = NAN;
    try {
      v[k] = p[k].as<double>();
    } catch (const YAML::Exception&) {}
    if (!std::isfinite(v[k])) throw Error(where + ": \"pose\" has a non-number");
  }
  if (std::sqrt(v[3] * v[3] + v[4] * v[4] + v[5] * v[5] + v[6] * v[6]) < 1e-6) throw Error(where + ": zero quaternion");
  return pose_from_xyz_quat(v);
}

FactorKind factor_kind(const YAML::Node& node, const std::string& where) {
  const YAML::Node t = member(node, "type", where);
  const std::string name = t.IsScalar() ? t.Scalar() : "";
  for (FactorKind k : kFactorKinds)
    if (name == to_string(k)) return k;
  throw Error(where + ": unknown factor type \"" + name + "\" (matching_cost, odometry, se3 or loop)");
}

}  // namespace

bool RunGraph::has(FactorKind kind) const { return count(kind) > 0; }

size_t RunGraph::count(FactorKind kind) const {
  size_t n = 0;
  for (const GraphEdge& e : edges) n += e.kind == kind;
  return n;
}

RunGraph read_graph_json(const std::string& path) {
  const YAML::Node root = load_json_object(path);
  const YAML::Node submaps = array_member(root, "submaps", path);
  const YAML::Node factors = array_member(root, "factors", path);
  RunGraph g;
  Eigen::Isometry3d T_submap0_world = Eigen::Isometry3d::Identity();
  for (size_t i = 0; i < submaps.size(); ++i) {
    const std::string where = item(path, "submaps", i);
    GraphNode n;
    n.id = integer(submaps[i], "id", where);
    if (n.id != static_cast<int>(i)) throw Error(where + ": id " + std::to_string(n.id) + ", expected " + std::to_string(i));
    n.first_frame = integer(submaps[i], "first_frame", where);
    const Eigen::Isometry3d T_world_submap = pose(submaps[i], where);
    if (i == 0) T_submap0_world = T_world_submap.inverse();
    n.T_out_submap = T_submap0_world * T_world_submap;
    g.nodes.push_back(n);
  }
  for (size_t i = 0; i < factors.size(); ++i) {
    const std::string where = item(path, "factors", i);
    GraphEdge e;
    e.kind = factor_kind(factors[i], where);
    e.source = integer(factors[i], "source", where);
    e.target = integer(factors[i], "target", where);
    for (int id : {e.source, e.target})
      if (id < 0 || id >= static_cast<int>(g.nodes.size()))
        throw Error(where + ": submap " + std::to_string(id) + " does not exist (" + std::to_string(g.nodes.size()) +
                    " submaps)");
    if (factors[i]["final_weight"]) e.weight = number(factors[i], "final_weight", where);
    g.edges.push_back(e);
  }
  return g;
}

RunStats read_stats_json(const std::string& path) {
  const YAML::Node root = load_json_object(path);
  RunStats s;
  const YAML::Node timing = member(root, "timing", path);
  if (!timing.IsMap()) throw Error(path + ": \"timing\" is not an object");
  for (const auto& kv : timing) {
    const std::string where = path + ": timing." + kv.first.Scalar();
    ModuleTiming t;
    t.module = kv.first.Scalar();
    t.mean_ms = number(kv.second, "mean_ms", where);
    t.std_ms = number(kv.second, "std_ms", where);
    t.max_ms = number(kv.second, "max_ms", where);
    t.count = static_cast<size_t>(std::max(0, integer(kv.second, "count", where)));
    s.timing.push_back(t);
  }
  const YAML::Node per = array_member(root, "per_submap", path);
  for (size_t i = 0; i < per.size(); ++i) {
    const std::string where = item(path, "per_submap", i);
    InsertionStats p;
    p.submaps = integer(per[i], "submaps", where);
    p.factors = integer(per[i], "factors", where);
    p.iterations = integer(per[i], "global_iterations", where);
    p.global_optimization_ms = number(per[i], "global_optimization_ms", where);
    s.per_submap.push_back(p);
  }
  return s;
}

std::string run_file(const std::string& dir, const std::string& name) {
  std::error_code ec;
  if (!std::filesystem::exists(dir, ec)) throw Error(dir + ": no such folder");
  if (!std::filesystem::is_directory(dir, ec)) throw Error(dir + ": is not a folder (expected the output folder of gcmap map)");
  return (std::filesystem::path(dir) / name).string();
}

RunData read_run(const std::string& dir, bool with_graph) {
  RunData run;
  run.map = read_point_cloud(run_file(dir, "map.ply"));
  run.trajectory = read_trajectory(run_file(dir, "trajectory.kitti")).poses;
  if (with_graph) {
    run.graph = read_graph_json(run_file(dir, "graph.json"));
    if (!run.trajectory.empty())
      for (GraphNode& n : run.graph.nodes) n.T_out_submap = run.trajectory.front() * n.T_out_submap;
  }
  return run;
}

}  // namespace gcmap::viz
