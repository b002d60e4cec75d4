#include "gcmap/session/localizer.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <functional>

#include "gcmap/core/error.hpp"
#include "gcmap/core/se3.hpp"
#include "gcmap/loop/loop_closure.hpp"

namespace gcmap {

const char* to_string(LocalizationStatus status) {
  switch (status) {
    case LocalizationStatus::tracking: return "tracking";
    case LocalizationStatus::lost: return "lost";
    case LocalizationStatus::relocalized: return "relocalized";
  }
  return "?";
}

Localizer::Localizer(std::shared_ptr<const PriorMap> prior, const MappingConfig& config,
                     std::shared_ptr<LinearizationBackend> backend, PipelineOptions options)
    : prior_(std::move(prior)),
      config_(config),
      backend_(backend ? std::move(backend) : std::make_shared<CpuBackend>()),
      options_(with_elevation_calibration(std::move(options), config.preprocess)),
      odometry_(config_.odometry, config_.preprocess, config_.imu, backend_) {
  config_.validate();
  if (!prior_ || prior_->submaps.empty()) throw Error("localize: the prior map has no submaps");
  for (const Submap& s : prior_->submaps) {
    if (!s.voxels || s.voxels->resolution() != config_.global.voxel_resolution)
      throw Error("global.voxel_resolution: differs from the prior map's voxel maps");
    for (size_t k = 0; k < s.descriptors.size(); ++k) {
      places_.add(s.descriptors[k]);
      place_keyframe_.emplace_back(s.id, static_cast<int>(k));
    }
  }
}

std::vector<int> Localizer::nearby_submaps(const Eigen::Isometry3d& T) const {
  std::vector<int> out;
  for (size_t j = 0; j < prior_->submaps.size(); ++j)
    if ((prior_->T_map_submap[j].translation() - T.translation()).norm() < config_.localize.submap_radius)
      out.push_back(static_cast<int>(j));
  return out;
}

double Localizer::map_overlap(const PointCloud& cloud, const Eigen::Isometry3d& T, const std::vector<int>& submaps) const {
  std::vector<PointTransform> to_submap;
  for (int j : submaps) to_submap.emplace_back(prior_->T_map_submap[j].inverse() * T);
  const size_t hits = tbb::parallel_reduce(
      tbb::blocked_range<size_t>(0, cloud.size(), 1024), size_t{0},
      [&](const tbb::blocked_range<size_t>& r, size_t n) {
        for (size_t i = r.begin(); i != r.end(); ++i)
          for (size_t k = 0; k < submaps.size(); ++k)
            if (prior_->submaps[submaps[k]].voxels->lookup(to_submap[k] * cloud.points[i]) >= 0) {
              ++n;
              break;
            }
        return n;
      },
      std::plus<>());
  return cloud.empty() ? 0.0 : static_cast<double>(hits) / cloud.size();
}

bool Localizer::track(const std::shared_ptr<const PointCloud>& cloud, const Eigen::Isometry3d& guess,
                      const std::optional<Eigen::Isometry3d>& previous, LocalizedFrame& out) {
  const std::vector<int> near = nearby_submaps(guess);
  std::vector<std::shared_ptr<const GaussianVoxelMap>> targets;
  std::vector<Eigen::Isometry3d> T_target_source;
  for (int j : near) {
    targets.push_back(prior_->submaps[j].voxels);
    T_target_source.push_back(prior_->T_map_submap[j].inverse() * guess);
  }
  std::vector<TargetOverlap> kept = overlapping_targets(*backend_, cloud, targets, T_target_source, config_.global.th_min);
  if (kept.size() > static_cast<size_t>(config_.localize.max_submaps)) {
    std::partial_sort(kept.begin(), kept.begin() + config_.localize.max_submaps, kept.end(),
                      [](const TargetOverlap& a, const TargetOverlap& b) { return a.overlap > b.overlap; });
    kept.resize(config_.localize.max_submaps);
  }
  // Keys: prior submaps by index (fixed), the previous frame (fixed), this frame.
  const int self = static_cast<int>(prior_->submaps.size()), prev = self + 1;
  FactorGraph graph;
  Values values{{self, guess}};
  std::set<int> fixed;
  std::vector<int> matched;
  for (const TargetOverlap& t : kept) {
    const int j = near[t.index];
    values[j] = prior_->T_map_submap[j];
    fixed.insert(j);
    matched.push_back(j);
    graph.add(std::make_shared<MatchingCostFactor>(self, j, cloud, prior_->submaps[j].voxels, TrialVoxels::kept));
  }
  if (matched.empty()) return false;
  if (previous && odometry_poses_.size() >= 2) {
    // The odometry motion, weakly: the map decides where it holds the frame.
    const Eigen::Isometry3d delta = odometry_poses_[odometry_poses_.size() - 2].inverse() * odometry_poses_.back();
    Matrix6d info = Matrix6d::Identity();
    info.diagonal() << 1e2, 1e2, 1e2, 1e1, 1e1, 1e1;
    values[prev] = *previous;
    fixed.insert(prev);
    graph.add(std::make_shared<RelativePoseFactor>(prev, self, delta, info));
  }
  LMConfig lc;
  lc.max_iterations = config_.odometry.max_iterations;
  LevenbergMarquardt(lc, backend_).optimize(graph, values, fixed);
  out.T_map_frame = values.at(self);
  out.prior_submaps = static_cast<int>(matched.size());
  out.map_overlap = map_overlap(*cloud, out.T_map_frame, matched);
  return out.map_overlap >= config_.localize.min_overlap;
}

std::optional<Eigen::Isometry3d> Localizer::global_initialization(const PointCloud& cloud) {
  const ScanContext query = make_scan_context(cloud, config_.loop.scan_context);
  const ScanContextDatabase::Result r = places_.query(query, places_.size(), config_.loop.num_candidates);
  if (r.place < 0) return std::nullopt;
  const auto [j, k] = place_keyframe_[r.place];
  const Submap& s = prior_->submaps[j];
  const Eigen::Isometry3d init =
      s.T_submap_keyframe[k] * Eigen::Isometry3d(Eigen::AngleAxisd(r.match.yaw, Eigen::Vector3d::UnitZ()));
  LoopConfig lc = config_.loop;
  lc.min_inlier_fraction = config_.localize.min_inlier_fraction;
  lc.max_inlier_rmse = config_.localize.max_inlier_rmse;
  const LoopVerification v = verify_loop(cloud, *s.cloud, init, lc);
  if (!v.accepted) return std::nullopt;
  return prior_->T_map_submap[j] * v.T_target_source;
}

LocalizedFrame Localizer::add_scan(PointCloud scan, double stamp) {
  if (!frames_.empty() && stamp < frames_.back().stamp)
    throw Error("localize: stamp " + std::to_string(stamp) + " s is before the previous scan's");
  Stopwatch w;
  LocalizedFrame f;
  f.index = static_cast<int>(frames_.size());
  f.stamp = stamp;
  if (!frames_.empty() && stamp - frames_.back().stamp > config_.odometry.max_gap) {
    // Across a gap dead reckoning would place the frame anywhere, and the map may well hold it
    // there too (streets repeat); the odometry's model lies behind. Both start again: the next
    // pose comes from the map's places.
    odometry_ = SweepOdometry(config_.odometry, config_.preprocess, config_.imu, backend_);
    initial_.reset();
    localized_once_ = false;
    lost_since_ = 0;
  }
  // Deskewed in place by the odometry: registered on the map, it gives the pose at the stamp.
  const std::shared_ptr<PointCloud> cloud =
      prepare_scan(std::move(scan), stamp, config_.preprocess, options_, backend_.get()).cloud;
  const SweepEstimate sweep = odometry_.track(cloud, stamp);
  odometry_poses_.push_back(sweep.T_world_frame);
  f.deskewed = sweep.deskewed;
  const bool usable = cloud && cloud->size() >= 100;
  // The odometry's first sweep, not deskewed (no motion known yet): global initialization waits a frame.
  const bool smeared = usable && cloud->has_times() && config_.preprocess.deskew && !sweep.deskewed;
  const LocalizedFrame* last = frames_.empty() ? nullptr : &frames_.back();
  // Dead reckoning by odometry from the last pose, also while lost: the map may take the frame back.
  std::optional<Eigen::Isometry3d> guess = initial_;
  if (last && (initial_ || localized_once_))
    guess = last->T_map_frame * (odometry_poses_[odometry_poses_.size() - 2].inverse() * odometry_poses_.back());
  f.T_map_frame = guess.value_or(Eigen::Isometry3d::Identity());
  const bool held = last && last->status != LocalizationStatus::lost && (initial_ || localized_once_);
  if (usable && guess && track(cloud, *guess, held ? std::optional(last->T_map_frame) : std::nullopt, f)) {
    f.status = LocalizationStatus::tracking;
  } else if (usable && !smeared && lost_since_++ % config_.localize.relocalize_every == 0) {
    if (const auto T = global_initialization(*cloud); T && track(cloud, *T, std::nullopt, f))
      f.status = LocalizationStatus::relocalized;
  }
  if (f.status != LocalizationStatus::lost) {
    lost_since_ = 0;
    localized_once_ = true;
  }
  f.ms = w.ms();
  frames_.push_back(f);
  return f;
}

}  // namespace gcmap
