#pragma once
// Merging mapping sessions into one frame (gcmap merge). Sessions are placed relative to each
// other by ScanContext places across sessions verified by GICP (as explicit loops are); then every
// overlapping pair of submaps of different sessions gets a matching-cost factor, each session
// keeps its own recorded factors, and LM optimizes all sessions jointly with the first session's
// first submap fixed. A session that shares no verified place with the others stays unconnected.
#include <memory>
#include <string>
#include <vector>

#include "gcmap/graph/levenberg_marquardt.hpp"
#include "gcmap/mapping/config.hpp"
#include "gcmap/mapping/factor_kind.hpp"
#include "gcmap/mapping/submap.hpp"

namespace gcmap {

// One session as merge takes it (session/session.hpp reads it from disk).
struct MergeInput {
  std::string name;                               // for messages (its folder)
  std::vector<Submap> submaps;                    // clouds, voxel maps, factor sources, keyframe descriptors
  std::vector<Eigen::Isometry3d> T_world_submap;  // the session's optimized poses, in its frame
  std::vector<FactorRecord> factors;              // its global graph
  std::vector<Eigen::Isometry3d> trajectory;      // per frame, in its frame
};

// A verified place between sessions: submap `source` of `session` against submap `target` of
// session `anchor`.
struct SessionPlacement {
  int session = -1, anchor = -1, source = -1, target = -1;
  bool accepted = false;
  double descriptor_distance = 0.0, inlier_fraction = 0.0, inlier_rmse = 0.0;
  double allowed_rmse = 0.0;  // the bound it was held to (see MergeConfig::max_rmse_ratio)
  Eigen::Isometry3d T_target_source = Eigen::Isometry3d::Identity();  // verified by GICP
};

struct MergeResult {
  std::vector<bool> connected;               // per session: placed relative to the first
  std::vector<SessionPlacement> placements;  // per session (the first and unconnected ones: anchor -1)
  std::vector<SessionPlacement> checks;      // every GICP verification, accepted or not (why one is unconnected)
  // Per connected session, the index of its first submap among the merged submaps (connected
  // sessions' submaps in input order); -1 when unconnected.
  std::vector<int> first_submap;
  std::vector<Eigen::Isometry3d> T_merged_submap;  // per merged submap, the first session's frame
  std::vector<FactorRecord> factors;               // of the joint graph, over merged submaps
  // Per session, every frame in the merged frame (empty when unconnected).
  std::vector<std::vector<Eigen::Isometry3d>> trajectories;
  size_t cross_factors = 0;  // matching-cost factors between sessions
  LMResult optimization;
  double placement_ms = 0.0, total_ms = 0.0;
};

// config: merge.*, loop.* (ScanContext and the GICP verification), global.th_min (overlap for a factor).
// The inputs' voxel maps and factor sources must be built. Throws Error naming the session for
// fewer than two sessions, a session without submaps or without ScanContext descriptors.
MergeResult merge_sessions(const std::vector<MergeInput>& sessions, const MappingConfig& config,
                           std::shared_ptr<LinearizationBackend> backend = nullptr);

}  // namespace gcmap
