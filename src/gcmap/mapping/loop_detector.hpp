#pragma once
// Explicit loops (paper Section III-C): ScanContext places of every keyframe, candidate search for
// each new submap among older ones, GICP verification of the best candidate.
#include <optional>
#include <vector>

#include "gcmap/core/timer.hpp"
#include "gcmap/loop/loop_closure.hpp"
#include "gcmap/mapping/submap.hpp"

namespace gcmap {

// An explicit loop candidate that passed or failed verification.
struct LoopRecord {
  int source = 0, target = 0;  // submaps
  double descriptor_distance = 0.0, inlier_fraction = 0.0, inlier_rmse = 0.0, conditioning = 0.0;
  bool accepted = false;
  Eigen::Isometry3d T_target_source = Eigen::Isometry3d::Identity();  // verified relative pose
};

struct LoopStats {
  TimingStats detection;     // ScanContext retrieval and matching, per submap (descriptors are made per keyframe)
  TimingStats verification;  // GICP, per candidate
};

// T_target_source of two submaps from a ScanContext match of the source's keyframe ka with the
// target's keyframe kb: the yaw only, the keyframes' positions taken as equal (GICP refines it).
Eigen::Isometry3d place_match_guess(const Submap& source, int ka, const Submap& target, int kb, double yaw);

class LoopDetector {
 public:
  explicit LoopDetector(const LoopConfig& config) : config_(config) {}

  // Every submap, in id order, once it is closed (its keyframe descriptors become places).
  void add_submap(const Submap& submap);
  // Searches the places of submaps older than submaps[id] - loop.exclude_recent for its keyframes and
  // verifies the best candidate; returns the accepted loop, if any. Every verified candidate is recorded.
  std::optional<LoopRecord> detect(int id, const std::vector<Submap>& submaps);

  const std::vector<LoopRecord>& loops() const { return loops_; }
  const LoopStats& stats() const { return stats_; }

 private:
  LoopConfig config_;
  ScanContextDatabase places_;                       // keyframe descriptors, in submap order
  std::vector<std::pair<int, int>> place_keyframe_;  // per place: (submap, index in submap)
  std::vector<size_t> submap_places_end_;            // per submap: places_ size once it was added
  std::vector<LoopRecord> loops_;
  LoopStats stats_;
};

}  // namespace gcmap
