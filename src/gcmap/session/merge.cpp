#include "gcmap/session/merge.hpp"

#include <algorithm>
#include <limits>
#include <map>
#include <optional>
#include <set>
#include <tuple>

#include "gcmap/core/error.hpp"
#include "gcmap/core/timer.hpp"
#include "gcmap/graph/factor_graph.hpp"
#include "gcmap/loop/loop_closure.hpp"
#include "gcmap/mapping/global_mapper.hpp"
#include "gcmap/mapping/loop_detector.hpp"

namespace gcmap {

namespace {

struct Place {
  int session, submap, keyframe;
};

struct Candidate {
  double distance, yaw;
  int submap, keyframe, place;  // query keyframe (of the session to place) and the place it matched
};

// The point-to-plane RMSE at which submap j of session s verifies against its neighbour at their
// optimized poses: the noise the session itself shows (0 for a session of one submap). Memoized:
// sessions are tried against each other repeatedly.
class OwnRmse {
 public:
  OwnRmse(const std::vector<MergeInput>& in, const LoopConfig& config) : in_(in), config_(config) {}
  double operator()(int s, int j) {
    const auto [it, added] = known_.try_emplace({s, j}, 0.0);
    const std::vector<Submap>& submaps = in_[s].submaps;
    const int n = static_cast<int>(submaps.size());
    if (added && n >= 2) {
      const int k = j + 1 < n ? j + 1 : j - 1;
      const Eigen::Isometry3d T_j_k = in_[s].T_world_submap[j].inverse() * in_[s].T_world_submap[k];
      it->second = verify_loop(*submaps[k].cloud, *submaps[j].cloud, T_j_k, config_).inlier_rmse;
    }
    return it->second;
  }

 private:
  const std::vector<MergeInput>& in_;
  const LoopConfig& config_;
  std::map<std::pair<int, int>, double> known_;
};

// Where session b lies in the reference frame, from the best verified ScanContext match of its
// keyframes with the places of the sessions placed so far.
std::optional<std::pair<SessionPlacement, Eigen::Isometry3d>> find_placement(const std::vector<MergeInput>& in,
                                                                             const std::vector<Eigen::Isometry3d>& T_ref_session,
                                                                             const std::vector<bool>& connected, int b,
                                                                             const MappingConfig& config, OwnRmse& own_rmse,
                                                                             std::vector<SessionPlacement>& checks) {
  ScanContextDatabase places;
  std::vector<Place> where;
  for (size_t a = 0; a < in.size(); ++a) {
    for (size_t j = 0; connected[a] && j < in[a].submaps.size(); ++j) {
      for (size_t k = 0; k < in[a].submaps[j].descriptors.size(); ++k) {
        places.add(in[a].submaps[j].descriptors[k]);
        where.push_back({static_cast<int>(a), static_cast<int>(j), static_cast<int>(k)});
      }
    }
  }
  std::vector<const ScanContext*> queries;
  std::vector<std::pair<int, int>> query_keyframe;
  for (size_t i = 0; i < in[b].submaps.size(); ++i) {
    for (size_t k = 0; k < in[b].submaps[i].descriptors.size(); ++k) {
      queries.push_back(&in[b].submaps[i].descriptors[k]);
      query_keyframe.emplace_back(static_cast<int>(i), static_cast<int>(k));
    }
  }
  const auto results = places.query(queries, places.size(), config.loop.num_candidates);
  std::vector<Candidate> candidates;
  for (size_t q = 0; q < results.size(); ++q) {
    if (results[q].place < 0 || results[q].match.distance > config.merge.max_descriptor_distance) continue;
    candidates.push_back(
        {results[q].match.distance, results[q].match.yaw, query_keyframe[q].first, query_keyframe[q].second, results[q].place});
  }
  std::stable_sort(candidates.begin(), candidates.end(),
                   [](const Candidate& x, const Candidate& y) { return x.distance < y.distance; });
  LoopConfig verification = config.loop;
  verification.min_inlier_fraction = config.merge.min_inlier_fraction;
  verification.max_inlier_rmse = std::numeric_limits<double>::infinity();  // decided below
  // Neighbouring keyframes propose the same submap pair again: each pair is verified once.
  std::set<std::tuple<int, int, int>> tried;
  for (const Candidate& c : candidates) {
    const Place& p = where[c.place];
    if (!tried.insert({c.submap, p.session, p.submap}).second) continue;
    if (tried.size() > static_cast<size_t>(config.merge.max_verifications)) break;
    const Submap& source = in[b].submaps[c.submap];
    const Submap& target = in[p.session].submaps[p.submap];
    const LoopVerification v =
        verify_loop(*source.cloud, *target.cloud, place_match_guess(source, c.keyframe, target, p.keyframe, c.yaw), verification);
    const double allowed_rmse =
        std::max(config.loop.max_inlier_rmse,
                 config.merge.max_rmse_ratio * std::max(own_rmse(b, c.submap), own_rmse(p.session, p.submap)));
    const bool accepted = v.accepted && v.inlier_rmse <= allowed_rmse;
    checks.push_back({b, p.session, c.submap, p.submap, accepted, c.distance, v.inlier_fraction, v.inlier_rmse, allowed_rmse,
                      v.T_target_source});
    if (!accepted) continue;
    const Eigen::Isometry3d T_ref_b = T_ref_session[p.session] * in[p.session].T_world_submap[p.submap] * v.T_target_source *
                                      in[b].T_world_submap[c.submap].inverse();
    return std::pair{checks.back(), T_ref_b};
  }
  return std::nullopt;
}

// Places every session it can, each against all sessions placed before it; returns the
// sessions' frames in the first session's frame.
std::vector<Eigen::Isometry3d> place_sessions(const std::vector<MergeInput>& in, const MappingConfig& config, MergeResult& r) {
  std::vector<Eigen::Isometry3d> T_ref_session(in.size(), Eigen::Isometry3d::Identity());
  r.connected.assign(in.size(), false);
  r.placements.assign(in.size(), {});
  r.connected[0] = true;
  OwnRmse own_rmse(in, config.loop);
  for (bool progress = true; progress;) {
    progress = false;
    for (size_t b = 1; b < in.size(); ++b) {
      if (r.connected[b]) continue;
      if (auto found = find_placement(in, T_ref_session, r.connected, static_cast<int>(b), config, own_rmse, r.checks)) {
        r.placements[b] = found->first;
        T_ref_session[b] = found->second;
        r.connected[b] = true;
        progress = true;
      }
    }
  }
  return T_ref_session;
}

std::shared_ptr<MatchingCostFactor> matching_cost(int source, int target, const Submap& s, const Submap& t,
                                                  const GlobalMappingConfig& config) {
  auto f = std::make_shared<MatchingCostFactor>(source, target, s.factor_source, t.voxels, TrialVoxels::kept_per_optimization);
  f->set_min_conditioning(config.min_conditioning);
  f->set_robust_width(static_cast<float>(config.robust_width));
  return f;
}

// Each session's own factors: its matching costs re-created, other kinds as relative poses at its
// optimized estimate.
void add_session_factors(const MergeInput& s, int offset, const GlobalMappingConfig& config, FactorGraph& graph,
                         std::vector<FactorRecord>& records) {
  for (const FactorRecord& f : s.factors) {
    const int source = offset + f.source, target = offset + f.target;
    if (f.kind == FactorKind::matching_cost) {
      graph.add(matching_cost(source, target, s.submaps[f.source], s.submaps[f.target], config));
    } else {
      const Eigen::Isometry3d T_target_source = s.T_world_submap[f.target].inverse() * s.T_world_submap[f.source];
      graph.add(std::make_shared<RelativePoseFactor>(target, source, T_target_source, odometry_factor_information()));
    }
    records.push_back({f.kind, source, target, f.overlap});
  }
}

Eigen::AlignedBox3d world_box(const Submap& s, const Eigen::Isometry3d& T_world_submap) {
  Eigen::AlignedBox3d local, world;
  for (const Eigen::Vector3f& p : s.cloud->points) local.extend(p.cast<double>());
  if (local.isEmpty()) return world;
  for (int c = 0; c < 8; ++c) world.extend(T_world_submap * local.corner(static_cast<Eigen::AlignedBox3d::CornerType>(c)));
  return world;
}

// A matching-cost factor from every submap to every submap of an earlier session it overlaps.
size_t add_cross_factors(const std::vector<const Submap*>& submaps, const std::vector<int>& session_of, const Values& values,
                         const MappingConfig& config, LinearizationBackend& backend, FactorGraph& graph,
                         std::vector<FactorRecord>& records) {
  std::vector<Eigen::AlignedBox3d> boxes;
  for (size_t u = 0; u < submaps.size(); ++u) boxes.push_back(world_box(*submaps[u], values.at(static_cast<int>(u))));
  size_t added = 0;
  for (size_t u = 0; u < submaps.size(); ++u) {
    std::vector<int> near;
    std::vector<std::shared_ptr<const GaussianVoxelMap>> targets;
    std::vector<Eigen::Isometry3d> T_target_source;
    for (size_t v = 0; v < u && session_of[v] < session_of[u]; ++v) {
      if (boxes[u].isEmpty() || !boxes[u].intersects(boxes[v])) continue;
      near.push_back(static_cast<int>(v));
      targets.push_back(submaps[v]->voxels);
      T_target_source.push_back(values.at(static_cast<int>(v)).inverse() * values.at(static_cast<int>(u)));
    }
    if (near.empty()) continue;
    for (const TargetOverlap& t :
         overlapping_targets(backend, submaps[u]->factor_source, targets, T_target_source, config.global.th_min)) {
      const int v = near[t.index];
      graph.add(matching_cost(static_cast<int>(u), v, *submaps[u], *submaps[v], config.global));
      records.push_back({FactorKind::matching_cost, static_cast<int>(u), v, t.overlap});
      ++added;
    }
  }
  return added;
}

void check_inputs(const std::vector<MergeInput>& in) {
  if (in.size() < 2) throw Error("merge: give at least two sessions");
  for (const MergeInput& s : in) {
    if (s.submaps.empty() || s.submaps.size() != s.T_world_submap.size()) throw Error(s.name + ": the session has no submaps");
    for (const Submap& m : s.submaps) {
      if (!m.voxels || !m.factor_source) throw Error(s.name + ": submap voxel maps are not built");
      if (m.descriptors.size() != m.keyframes.size() || m.keyframes.empty())
        throw Error(s.name + ": the session has no ScanContext descriptors (it was mapped with loop.enabled: false)");
    }
    for (const FactorRecord& f : s.factors)
      if (f.source < 0 || f.target < 0 || static_cast<size_t>(std::max(f.source, f.target)) >= s.submaps.size())
        throw Error(s.name + ": a factor names a submap that does not exist");
  }
}

// Every frame moves with the submap it was mapped in (the last one begun at or before it).
std::vector<Eigen::Isometry3d> moved_trajectory(const MergeInput& s, const Eigen::Isometry3d* T_merged_submap) {
  std::vector<Eigen::Isometry3d> out;
  size_t i = 0;
  for (size_t f = 0; f < s.trajectory.size(); ++f) {
    while (i + 1 < s.submaps.size() && s.submaps[i + 1].keyframes.front() <= static_cast<int>(f)) ++i;
    out.push_back(T_merged_submap[i] * s.T_world_submap[i].inverse() * s.trajectory[f]);
  }
  return out;
}

}  // namespace

MergeResult merge_sessions(const std::vector<MergeInput>& in, const MappingConfig& config,
                           std::shared_ptr<LinearizationBackend> backend) {
  check_inputs(in);
  config.validate();
  if (!backend) backend = std::make_shared<CpuBackend>();
  Stopwatch w;
  MergeResult r;
  const std::vector<Eigen::Isometry3d> T_ref_session = place_sessions(in, config, r);
  r.placement_ms = w.ms();

  FactorGraph graph;
  Values values;
  std::vector<const Submap*> submaps;
  std::vector<int> session_of;
  r.first_submap.assign(in.size(), -1);
  for (size_t s = 0; s < in.size(); ++s) {
    if (!r.connected[s]) continue;
    r.first_submap[s] = static_cast<int>(submaps.size());
    for (size_t i = 0; i < in[s].submaps.size(); ++i) {
      values[static_cast<int>(submaps.size())] = T_ref_session[s] * in[s].T_world_submap[i];
      submaps.push_back(&in[s].submaps[i]);
      session_of.push_back(static_cast<int>(s));
    }
    add_session_factors(in[s], r.first_submap[s], config.global, graph, r.factors);
    const SessionPlacement& p = r.placements[s];
    if (p.anchor < 0) continue;
    // The verified place, as explicit loops are kept: it lets go once the matching costs agree.
    const int source = r.first_submap[s] + p.source, target = r.first_submap[p.anchor] + p.target;
    graph.add(make_loop_factor(target, source, p.T_target_source, config.loop));
    r.factors.push_back({FactorKind::loop, source, target, 0.0});
  }
  r.cross_factors = add_cross_factors(submaps, session_of, values, config, *backend, graph, r.factors);

  LMConfig lc;
  lc.max_iterations = config.merge.max_iterations;
  r.optimization = LevenbergMarquardt(lc, backend).optimize(graph, values, {0});
  for (size_t u = 0; u < submaps.size(); ++u) r.T_merged_submap.push_back(values.at(static_cast<int>(u)));
  r.trajectories.resize(in.size());
  for (size_t s = 0; s < in.size(); ++s)
    if (r.connected[s]) r.trajectories[s] = moved_trajectory(in[s], &r.T_merged_submap[r.first_submap[s]]);
  r.total_ms = w.ms();
  return r;
}

}  // namespace gcmap
