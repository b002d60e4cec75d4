#pragma once
// Benchmark graphs over the five real kitti07 submap clouds (../shared/data/kitti07_submaps).
#include <filesystem>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "gcmap/core/timer.hpp"
#include "gcmap/graph/matching_graph.hpp"
#include "gcmap/io/point_cloud_io.hpp"
#include "gcmap/io/trajectory_io.hpp"

namespace gcmap::bench {

struct Kitti07 {
  Trajectory reference;
  std::vector<ScanNode> nodes;
  size_t points_per_cloud = 0;  // mean

  // Empty when the data folder is absent.
  static std::optional<Kitti07> load() {
    const std::string dir = std::string(GCMAP_SHARED_DATA) + "/kitti07_submaps";
    if (!std::filesystem::exists(dir)) return std::nullopt;
    Kitti07 k;
    k.reference = read_trajectory(dir + "/graph.txt");
    size_t total = 0;
    for (int c = 0; c < 5; ++c) {
      k.nodes.push_back(
          make_scan_node(read_point_cloud(dir + "/00000" + std::to_string(c) + "/points.bin", BinFields::xyz), 1.0));
      total += k.nodes.back().cloud->size();
    }
    k.points_per_cloud = total / 5;
    return k;
  }

  // The (source, target) variables of num_factors matching-cost factors over max(5, num_factors / 5)
  // variables that cycle through the 5 clouds: each factor joins two variables holding different
  // clouds, so every factor is a real overlapping pair.
  static std::vector<std::pair<int, int>> graph_pairs(int num_factors) {
    const int num_vars = std::max(5, num_factors / 5);
    std::vector<std::pair<int, int>> pairs;
    for (int f = 0; pairs.size() < static_cast<size_t>(num_factors); ++f) {
      const int u = f % num_vars, step = 1 + (f / num_vars) % 4;
      const int v = (u + step) % num_vars;
      if (u % 5 != v % 5) pairs.emplace_back(u, v);
    }
    return pairs;
  }

  // That graph with the variables at the clouds' reference poses. The variables share the five
  // clouds and voxel maps, few enough to stay mostly in the caches; with `distinct`, each variable holds
  // its own copy, as each submap of a mapping run does.
  void make_graph(int num_factors, FactorGraph& graph, Values& values, bool distinct = false,
                  TrialVoxels trial_voxels = TrialVoxels::look_up) const {
    const int num_vars = std::max(5, num_factors / 5);
    std::vector<ScanNode> own;
    for (int v = 0; v < num_vars; ++v) {
      values[v] = reference.poses[v % 5];
      own.push_back(distinct ? ScanNode{std::make_shared<PointCloud>(*nodes[v % 5].cloud),
                                        std::make_shared<GaussianVoxelMap>(*nodes[v % 5].voxels)}
                             : nodes[v % 5]);
    }
    for (const auto& [u, v] : graph_pairs(num_factors))
      graph.add(std::make_shared<MatchingCostFactor>(u, v, own[u].cloud, own[v].voxels, trial_voxels));
  }
};

// values with every pose but the first moved by a random step of up to `meters` and `radians` per
// axis (fixed seed).
inline Values perturbed(const Values& values, double meters, double radians) {
  std::mt19937 rng(42);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Values out = values;
  for (auto& [key, T] : out) {
    if (key == out.begin()->first) continue;
    Vector6d d;
    for (int k = 0; k < 6; ++k) d[k] = u(rng) * (k < 3 ? radians : meters);
    T = T * se3_exp(d);
  }
  return out;
}

struct Timing {
  double linearize_ms = 0.0, trial_ms = 0.0;
};

// Mean ms of one batched linearization and one trial evaluation of the whole graph, after a
// warm-up call (uploads, batch layout).
inline Timing time_backend(LinearizationBackend& backend, const FactorGraph& graph, const Values& values, int repeats) {
  std::vector<Factor*> factors;
  std::vector<FactorPoses> poses;
  for (const auto& f : graph.factors) {
    factors.push_back(f.get());
    poses.push_back({&values.at(f->keys()[0]), &values.at(f->keys()[1])});
  }
  std::vector<FactorLinearization> lin(factors.size());
  std::vector<double> errors(factors.size());
  backend.linearize(factors, poses, lin);  // warm-up: uploads, batch layout
  Timing t;
  for (int r = 0; r < repeats; ++r) {
    Stopwatch w;
    backend.linearize(factors, poses, lin);
    t.linearize_ms += w.lap_ms();
    backend.trial_errors(factors, poses, errors);
    t.trial_ms += w.lap_ms();
  }
  t.linearize_ms /= repeats;
  t.trial_ms /= repeats;
  return t;
}

}  // namespace gcmap::bench
