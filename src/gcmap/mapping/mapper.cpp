#include "gcmap/mapping/mapper.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

#include "gcmap/core/preprocess.hpp"
#include "gcmap/core/timer.hpp"
#include "gcmap/mapping/loop_closure.hpp"
#include "gcmap/registration/registration.hpp"
#include "gcmap/registration/vgicp.hpp"

namespace gcmap {

double TimingStats::mean() const {
  if (samples_ms.empty()) return 0.0;
  double s = 0;
  for (double v : samples_ms) s += v;
  return s / samples_ms.size();
}
double TimingStats::stddev() const {
  if (samples_ms.size() < 2) return 0.0;
  const double m = mean();
  double s = 0;
  for (double v : samples_ms) s += (v - m) * (v - m);
  return std::sqrt(s / samples_ms.size());
}
double TimingStats::max() const {
  return samples_ms.empty() ? 0.0 : *std::max_element(samples_ms.begin(), samples_ms.end());
}

namespace {
// At most n points, by an even stride: deterministic and spatially uniform (points are in voxel order).
PointCloud evenly_subsampled(PointCloud cloud, int n) {
  if (static_cast<int>(cloud.size()) <= n) return cloud;
  std::vector<char> keep(cloud.size(), 0);
  const double stride = static_cast<double>(cloud.size()) / n;
  for (int i = 0; i < n; ++i) keep[static_cast<size_t>(i * stride)] = 1;
  cloud.filter(keep);
  return cloud;
}

LMConfig lm_config(int iterations, double relative_error_tol = LMConfig{}.relative_error_tol) {
  LMConfig c;
  c.max_iterations = iterations;
  c.relative_error_tol = relative_error_tol;
  return c;
}
}  // namespace

Mapper::Mapper(const MappingConfig& config, std::shared_ptr<LinearizationBackend> backend)
    : config_(config),
      backend_(backend ? std::move(backend) : std::make_shared<CpuBackend>()),
      lm_(lm_config(config.global.max_iterations, config.global.relative_error_tol), backend_) {
  config_.validate();
}

void Mapper::add_frame(int frame, const std::shared_ptr<const PointCloud>& cloud, const Eigen::Isometry3d& T_odom) {
  if (frame != static_cast<int>(frames_.size())) throw std::logic_error("Mapper: frames must be consecutive");
  frames_.push_back({-1, T_odom});
  keyframe_location_.emplace_back(-1, -1);
  auto anchor_to_last = [&] {
    if (!open_.empty()) frames_.back().anchor = open_.back().frame;
    else if (!submaps_.empty()) frames_.back().anchor = submaps_.back().keyframes.back();
  };
  if (!cloud || cloud->size() < 100) {
    anchor_to_last();
    return;
  }
  if (!open_.empty()) {
    const Keyframe& last = open_.back();
    const double ov = overlap(*cloud, *last.voxels, last.T_odom.inverse() * T_odom);
    if (ov > config_.local.th_max) {
      anchor_to_last();
      return;
    }
    // After a gap (dropped scans) the frame may not overlap the submap at all: it starts a new one
    // rather than joining a local graph it has no factor into.
    if (ov < config_.local.th_min) close_submap();
  }
  auto voxels = std::make_shared<GaussianVoxelMap>(config_.local.voxel_resolution);
  voxels->insert(*cloud);
  voxels->finalize();
  ScanContext descriptor;
  if (config_.loop.enabled) descriptor = make_scan_context(*cloud, config_.loop.scan_context);
  open_.push_back({frame, T_odom, cloud, voxels, std::move(descriptor)});
  frames_.back().anchor = frame;
  if (open_.size() >= 2) {
    const Keyframe& first = open_.front();
    const double ov = overlap(*cloud, *first.voxels, first.T_odom.inverse() * T_odom);
    if (ov < config_.local.th_min || static_cast<int>(open_.size()) >= config_.local.max_keyframes) close_submap();
  }
}

void Mapper::close_submap() {
  if (open_.empty()) return;
  Submap s;
  s.id = static_cast<int>(submaps_.size());
  s.T_odom = open_.front().T_odom;
  const int n = static_cast<int>(open_.size());
  Values local;
  for (int k = 0; k < n; ++k) local[k] = s.T_odom.inverse() * open_[k].T_odom;
  if (n >= 2) {
    // Fully connected: every keyframe pair gets a VGICP factor (source later, target earlier).
    Stopwatch w;
    FactorGraph g;
    for (int b = 1; b < n; ++b) {
      auto source = config_.local.factor_source_points > 0
                        ? std::make_shared<const PointCloud>(evenly_subsampled(*open_[b].cloud, config_.local.factor_source_points))
                        : open_[b].cloud;
      for (int a = 0; a < b; ++a) g.add(std::make_shared<MatchingCostFactor>(b, a, source, open_[a].voxels));
    }
    stats_.local_factors.add(w.lap_ms());
    LevenbergMarquardt lm(lm_config(config_.local.max_iterations, config_.local.relative_error_tol), backend_);
    lm.optimize(g, local, {0});
    stats_.local_optimization.add(w.lap_ms());
  }
  // Merge: keyframe clouds in the submap frame, voxel-averaged means and covariances.
  PointCloud merged;
  for (int k = 0; k < n; ++k) {
    s.keyframes.push_back(open_[k].frame);
    s.T_submap_keyframe.push_back(local.at(k));
    const PointCloud c = transformed(*open_[k].cloud, local.at(k));
    merged.points.insert(merged.points.end(), c.points.begin(), c.points.end());
    merged.covs.insert(merged.covs.end(), c.covs.begin(), c.covs.end());
  }
  merged = voxel_downsample(merged, config_.local.submap_downsample);
  merged = evenly_subsampled(std::move(merged), config_.local.max_submap_points);
  auto voxels = std::make_shared<GaussianVoxelMap>(config_.global.voxel_resolution);
  voxels->insert(merged);
  voxels->finalize();
  s.factor_source = std::make_shared<const PointCloud>(evenly_subsampled(merged, config_.global.factor_source_points));
  s.cloud = std::make_shared<const PointCloud>(std::move(merged));
  s.voxels = voxels;
  for (int k = 0; k < n; ++k) keyframe_location_[open_[k].frame] = {s.id, k};
  if (config_.loop.enabled) {
    for (int k = 0; k < n; ++k) {
      places_.add(std::move(open_[k].descriptor));
      place_keyframe_.emplace_back(s.id, k);
    }
  }
  submap_places_end_.push_back(places_.size());
  open_.clear();
  insert_submap(std::move(s));
}

void Mapper::insert_submap(Submap s) {
  const int id = s.id;
  if (id == 0) {
    values_[0] = Eigen::Isometry3d::Identity();
  } else {
    const Submap& prev = submaps_.back();
    values_[id] = values_.at(prev.id) * (prev.T_odom.inverse() * s.T_odom);
  }
  submaps_.push_back(std::move(s));
  const Submap& cur = submaps_.back();
  if (id == 0) {
    stats_.per_submap.push_back({1, 0, 0.0, 0});
    return;
  }

  Stopwatch w;
  const int first = config_.global.mode == "sliding-window" ? std::max(0, id - config_.global.window) : 0;
  std::vector<char> connected(id, 0);
  if (connect_overlapping(id, first, connected) == 0) {
    // Only where the submap would otherwise be disconnected.
    const Submap& prev = submaps_[id - 1];
    Matrix6d info = Matrix6d::Identity();
    info.diagonal() << 1e4, 1e4, 1e4, 1e3, 1e3, 1e3;
    graph_.add(std::make_shared<RelativePoseFactor>(id - 1, id, prev.T_odom.inverse() * cur.T_odom, info));
    factor_info_.push_back({"odometry", id, id - 1, 0.0, 0.0});
    connected[id - 1] = 1;
  }
  stats_.global_factors.add(w.lap_ms());
  const bool loop = config_.loop.enabled && config_.global.mode == "full" && close_explicit_loop(id);
  w.lap_ms();  // loop time is counted in its own statistics
  // A verified loop says the estimate was off where it closes, so the revisit factors made at that
  // estimate may sit in a wrong minimum: the loop first steers without them.
  int iterations = 0;
  if (loop) iterations += lm_.optimize(without_revisit_factors(), values_, {0}).iterations;
  iterations += lm_.optimize(graph_, values_, {0}).iterations;
  double opt_ms = w.lap_ms();
  if (loop) {
    // The implicit loop closure: the corrected estimate now overlaps submaps it missed before.
    const int added = connect_overlapping(id, first, connected);
    stats_.global_factors.add(w.lap_ms());
    if (added) iterations += lm_.optimize(graph_, values_, {0}).iterations;
    opt_ms += w.lap_ms();
  }
  stats_.global_optimization.add(opt_ms);
  stats_.per_submap.push_back({id + 1, static_cast<int>(graph_.factors.size()), opt_ms, iterations});
}

FactorGraph Mapper::without_revisit_factors() const {
  const auto revisit = [&](const FactorInfo& f) {
    return f.type != "loop" && f.type != "odometry" && std::abs(f.source - f.target) > config_.loop.exclude_recent;
  };
  FactorGraph steer;
  std::vector<char> constrained(submaps_.size(), 0);
  for (size_t f = 0; f < graph_.factors.size(); ++f) {
    if (revisit(factor_info_[f])) continue;
    steer.add(graph_.factors[f]);
    constrained[factor_info_[f].source] = constrained[factor_info_[f].target] = 1;
  }
  // A submap held only by revisit factors keeps them (LM needs every pose constrained).
  for (size_t f = 0; f < graph_.factors.size(); ++f) {
    const FactorInfo& info = factor_info_[f];
    if (revisit(info) && (!constrained[info.source] || !constrained[info.target])) steer.add(graph_.factors[f]);
  }
  return steer;
}

int Mapper::connect_overlapping(int id, int first, std::vector<char>& connected) {
  const Submap& cur = submaps_[id];
  std::vector<int> candidates;
  std::vector<std::shared_ptr<const GaussianVoxelMap>> targets;
  std::vector<Eigen::Isometry3d> T_target_source;
  for (int j = first; j < id; ++j) {
    if (connected[j]) continue;
    candidates.push_back(j);
    targets.push_back(submaps_[j].voxels);
    T_target_source.push_back(values_.at(j).inverse() * values_.at(id));
  }
  std::vector<double> overlaps(candidates.size());
  backend_->overlaps(cur.factor_source, targets, T_target_source, overlaps);
  int added = 0;
  for (size_t k = 0; k < candidates.size(); ++k) {
    const int j = candidates[k];
    const double ov = overlaps[k];
    if (ov < config_.global.th_min) continue;
    if (config_.global.factor == "se3") {
      // Ablation "Proposed (SE3)": a relative-pose constraint from kNN GICP scan matching with the
      // Hessian as information and a Huber kernel.
      const GicpTarget target(submaps_[j].cloud);
      const RegistrationResult r = align_gicp(*cur.cloud, target, values_.at(j).inverse() * values_.at(id));
      graph_.add(std::make_shared<RelativePoseFactor>(j, id, r.T_target_source, r.H, RobustKernel::huber(10.0)));
      factor_info_.push_back({"se3", id, j, ov, 0.0});
    } else {
      graph_.add(std::make_shared<MatchingCostFactor>(id, j, cur.factor_source, submaps_[j].voxels));
      factor_info_.push_back({"matching_cost", id, j, ov, 0.0});
    }
    connected[j] = 1;
    ++added;
  }
  return added;
}

bool Mapper::close_explicit_loop(int id) {
  const LoopConfig& lc = config_.loop;
  const int last_searchable = id - lc.exclude_recent;  // submaps [0, last_searchable) are searched
  if (last_searchable <= 0) return false;
  Stopwatch w;
  const size_t end = submap_places_end_[last_searchable - 1];
  const size_t begin = submap_places_end_[id - 1];
  std::vector<const ScanContext*> queries;
  for (size_t q = begin; q < submap_places_end_[id]; ++q) queries.push_back(&places_.place(q));
  const std::vector<ScanContextDatabase::Result> results = places_.query(queries, end, lc.num_candidates);
  ScanContextDatabase::Result best;
  size_t best_query = 0;
  for (size_t q = 0; q < results.size(); ++q) {
    if (results[q].place >= 0 && results[q].match.distance < best.match.distance) {
      best = results[q];
      best_query = begin + q;
    }
  }
  stats_.loop_detection.add(w.lap_ms());
  if (best.place < 0 || best.match.distance > lc.max_descriptor_distance) return false;

  // Keyframe a (this submap) matched keyframe b (submap j) with R_b_a = Rz(yaw), positions unknown.
  const auto [j, kb] = place_keyframe_[best.place];
  const int ka = place_keyframe_[best_query].second;
  const Eigen::Isometry3d T_b_a(Eigen::AngleAxisd(best.match.yaw, Eigen::Vector3d::UnitZ()));
  const Eigen::Isometry3d init = submaps_[j].T_submap_keyframe[kb] * T_b_a * submaps_[id].T_submap_keyframe[ka].inverse();
  const LoopVerification v = verify_loop(*submaps_[id].cloud, *submaps_[j].cloud, init, lc);
  stats_.loop_verification.add(w.lap_ms());
  loops_.push_back({id, j, best.match.distance, v.inlier_fraction, v.inlier_rmse, v.accepted, v.T_target_source});
  if (!v.accepted) return false;
  graph_.add(make_loop_factor(j, id, v.T_target_source, lc));
  factor_info_.push_back({"loop", id, j, 0.0, 0.0});
  return true;
}

void Mapper::finish() {
  close_submap();
  if (graph_.factors.empty()) return;
  LevenbergMarquardt final_lm(lm_config(config_.global.final_iterations), backend_);
  Stopwatch w;
  stats_.final_iterations = final_lm.optimize(graph_, values_, {0}).iterations;
  stats_.final_optimization_ms = w.ms();
  stats_.global_optimization.add(stats_.final_optimization_ms);
}

std::vector<Eigen::Isometry3d> Mapper::trajectory() const {
  std::vector<Eigen::Isometry3d> out(frames_.size(), Eigen::Isometry3d::Identity());
  auto keyframe_world = [&](int kf) -> Eigen::Isometry3d {
    const auto [s, k] = keyframe_location_[kf];
    if (s >= 0) return values_.at(s) * submaps_[s].T_submap_keyframe[k];
    // A keyframe of the open submap (only before finish()): placed from the last submap by odometry.
    if (submaps_.empty()) return frames_[kf].T_odom;
    const Submap& last = submaps_.back();
    return values_.at(last.id) * last.T_odom.inverse() * frames_[kf].T_odom;
  };
  for (size_t f = 0; f < frames_.size(); ++f) {
    const int anchor = frames_[f].anchor;
    if (anchor < 0) {
      out[f] = frames_[f].T_odom;
      continue;
    }
    out[f] = keyframe_world(anchor) * frames_[anchor].T_odom.inverse() * frames_[f].T_odom;
  }
  const Eigen::Isometry3d T0_inv = out.empty() ? Eigen::Isometry3d::Identity() : out.front().inverse();
  for (auto& T : out) T = normalized(T0_inv * T);
  return out;
}

std::vector<FactorInfo> Mapper::factors() const {
  std::vector<FactorInfo> out = factor_info_;
  tbb::parallel_for(size_t{0}, graph_.factors.size(), [&](size_t f) {
    const Factor& factor = *graph_.factors[f];
    const Eigen::Isometry3d* poses[2] = {&values_.at(factor.keys()[0]), &values_.at(factor.keys()[1])};
    if (const auto* m = dynamic_cast<const MatchingCostFactor*>(&factor)) {
      out[f].error = evaluate_vgicp(m->source(), m->target(), poses[1]->inverse() * *poses[0]).error;
    } else if (const auto* r = dynamic_cast<const RelativePoseFactor*>(&factor)) {
      RelativePoseFactor copy = *r;  // linearize() records the robust weight in the factor
      FactorLinearization lin;
      copy.linearize(poses, lin);
      out[f].error = lin.error;
      out[f].weight = copy.weight();
    }
  });
  return out;
}

PointCloud Mapper::assemble_map(double resolution) const {
  PointCloud map;
  for (const Submap& s : submaps_) {
    const PointCloud c = transformed(*s.cloud, values_.at(s.id));
    map.points.insert(map.points.end(), c.points.begin(), c.points.end());
  }
  if (!frames_.empty() && !submaps_.empty()) {
    // Express the map in the output frame (first frame identity), like the trajectory.
    const auto [s, k] = keyframe_location_[0];
    if (s >= 0) {
      const Eigen::Isometry3d T0 = values_.at(s) * submaps_[s].T_submap_keyframe[k];
      map = transformed(map, T0.inverse());
    }
  }
  return voxel_downsample(map, resolution);
}

}  // namespace gcmap
