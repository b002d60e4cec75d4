#include "gcmap/mapping/loop_detector.hpp"

#include "gcmap/loop/loop_closure.hpp"

namespace gcmap {

Eigen::Isometry3d place_match_guess(const Submap& source, int ka, const Submap& target, int kb, double yaw) {
  // Keyframe a (source) matched keyframe b (target) with R_b_a = Rz(yaw), positions unknown.
  const Eigen::Isometry3d T_b_a(Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()));
  return target.T_submap_keyframe[kb] * T_b_a * source.T_submap_keyframe[ka].inverse();
}

void LoopDetector::add_submap(const Submap& submap) {
  for (size_t k = 0; k < submap.descriptors.size(); ++k) {
    places_.add(submap.descriptors[k]);
    place_keyframe_.emplace_back(submap.id, static_cast<int>(k));
  }
  submap_places_end_.push_back(places_.size());
}

std::optional<LoopRecord> LoopDetector::detect(int id, const std::vector<Submap>& submaps) {
  const int last_searchable = id - config_.exclude_recent;  // submaps [0, last_searchable) are searched
  if (last_searchable <= 0) return std::nullopt;
  Stopwatch w;
  const size_t end = submap_places_end_[last_searchable - 1];
  const size_t begin = submap_places_end_[id - 1];
  std::vector<const ScanContext*> queries;
  for (size_t q = begin; q < submap_places_end_[id]; ++q) queries.push_back(&places_.place(q));
  const std::vector<ScanContextDatabase::Result> results = places_.query(queries, end, config_.num_candidates);
  ScanContextDatabase::Result best;
  size_t best_query = 0;
  for (size_t q = 0; q < results.size(); ++q) {
    if (results[q].place >= 0 && results[q].match.distance < best.match.distance) {
      best = results[q];
      best_query = begin + q;
    }
  }
  stats_.detection.add(w.lap_ms());
  if (best.place < 0 || best.match.distance > config_.max_descriptor_distance) return std::nullopt;

  const auto [j, kb] = place_keyframe_[best.place];
  const int ka = place_keyframe_[best_query].second;
  const Eigen::Isometry3d init = place_match_guess(submaps[id], ka, submaps[j], kb, best.match.yaw);
  const LoopVerification v = verify_loop(*submaps[id].cloud, *submaps[j].cloud, init, config_);
  stats_.verification.add(w.lap_ms());
  loops_.push_back({id, j, best.match.distance, v.inlier_fraction, v.inlier_rmse, v.conditioning, v.accepted, v.T_target_source});
  if (!v.accepted) return std::nullopt;
  return loops_.back();
}

}  // namespace gcmap
