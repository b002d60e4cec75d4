#include "gcmap/mapping/submap_builder.hpp"

#include <algorithm>
#include <cmath>

#include "gcmap/core/preprocess.hpp"
#include "gcmap/graph/levenberg_marquardt.hpp"
#include "gcmap/registration/vgicp.hpp"

namespace gcmap {

const char* to_string(FrameStatus status) {
  switch (status) {
    case FrameStatus::keyframe: return "keyframe";
    case FrameStatus::skipped: return "skipped";
    case FrameStatus::unusable: return "unusable";
  }
  return "?";
}

PointCloud evenly_subsampled(PointCloud cloud, int n) {
  if (static_cast<int>(cloud.size()) <= n) return cloud;
  std::vector<char> keep(cloud.size(), 0);
  const double stride = static_cast<double>(cloud.size()) / n;
  for (int i = 0; i < n; ++i) keep[static_cast<size_t>(i * stride)] = 1;
  return cloud.selected(keep);  // not filter(): submaps keep their clouds, so no spare capacity
}

SubmapBuilder::SubmapBuilder(const LocalMappingConfig& local, const GlobalMappingConfig& global, const LoopConfig& loop,
                             std::shared_ptr<LinearizationBackend> backend)
    : config_(local), global_(global), loop_(loop), backend_(std::move(backend)) {}

KeyframeShape keyframe_shape(const PointCloud& cloud, const LocalMappingConfig& local, const LoopConfig& loop) {
  auto voxels = std::make_shared<GaussianVoxelMap>(local.voxel_resolution);
  voxels->insert(cloud);
  voxels->finalize();
  KeyframeShape shape{std::move(voxels), {}};
  if (loop.enabled) shape.descriptor = make_scan_context(cloud, loop.scan_context);
  return shape;
}

SubmapBuilder::Keyframe SubmapBuilder::make_keyframe(int frame, const Eigen::Isometry3d& T_odom,
                                                     const std::shared_ptr<const PointCloud>& cloud,
                                                     std::optional<KeyframeShape> shape) const {
  if (!shape) shape = keyframe_shape(*cloud, config_, loop_);
  return {frame, T_odom, cloud, std::move(shape->voxels), std::move(shape->descriptor), std::nullopt};
}

bool SubmapBuilder::revise(int frame, const std::shared_ptr<const PointCloud>& cloud, const Eigen::Isometry3d& T_odom) {
  for (Keyframe& k : open_)
    if (k.frame == frame && cloud && cloud->size() >= 100) {
      Keyframe revised = make_keyframe(frame, T_odom, cloud, std::nullopt);
      revised.gyro = k.gyro;
      k = std::move(revised);
      return true;
    }
  return false;
}

SubmapBuilder::Result SubmapBuilder::add_frame(int frame, const std::shared_ptr<const PointCloud>& cloud,
                                               const Eigen::Isometry3d& T_odom, std::optional<KeyframeShape> shape,
                                               const std::optional<GyroRotation>& gyro) {
  Result r;
  if (complete_) r.closed = close();
  r.anchor = last_keyframe_;
  since_keyframe_ = since_keyframe_ && gyro ? std::optional(since_keyframe_->then(*gyro)) : std::nullopt;
  if (!cloud || cloud->size() < 100) return r;
  if (!open_.empty()) {
    const Keyframe& last = open_.back();
    const double ov = overlap(*cloud, *last.voxels, last.T_odom.inverse() * T_odom);
    if (ov > config_.th_max) {
      r.status = FrameStatus::skipped;
      return r;
    }
    // After a gap (dropped scans) the frame may not overlap the submap at all: it starts a new one
    // rather than joining a local graph it has no factor into.
    if (ov < config_.th_min) r.closed = close();
  }
  open_.push_back(make_keyframe(frame, T_odom, cloud, std::move(shape)));
  if (open_.size() >= 2) open_.back().gyro = since_keyframe_;
  since_keyframe_ = GyroRotation{};
  r.status = FrameStatus::keyframe;
  r.anchor = last_keyframe_ = frame;
  if (open_.size() >= 2) {
    const Keyframe& first = open_.front();
    const double ov = overlap(*cloud, *first.voxels, first.T_odom.inverse() * T_odom);
    complete_ = ov < config_.th_min || static_cast<int>(open_.size()) >= config_.max_keyframes;
  }
  return r;
}

namespace {

// m: how far a factor alone would move its source keyframe from the joint optimum, its target held
// fixed (one Gauss-Newton step: the factor's minimum in its quadratic model). Like a submap pair's
// re-registration shift (mapping/quality.cpp), from the final estimate; NaN when unconstrained.
double single_factor_shift(Factor& f, const Values& poses) {
  const Eigen::Isometry3d* p[2] = {&poses.at(f.keys()[0]), &poses.at(f.keys()[1])};
  FactorLinearization lin;
  f.linearize(p, lin);
  const Eigen::LDLT<Matrix6d> ldlt(lin.H.topLeftCorner<6, 6>());
  if (ldlt.info() != Eigen::Success || !ldlt.isPositive()) return std::nan("");
  const Vector6d step = -ldlt.solve(lin.b.head<6>());
  return step.tail<3>().norm();  // [rotation; translation]
}

// The median over consecutive keyframes: they overlap most (keyframes farther apart may hardly),
// and consecutive submaps are the fallback baseline, so the two figures compare like with like.
std::optional<float> keyframe_noise(const std::vector<std::shared_ptr<Factor>>& consecutive, const Values& poses) {
  std::vector<double> shifts;
  for (const auto& f : consecutive)
    if (const double s = single_factor_shift(*f, poses); std::isfinite(s)) shifts.push_back(s);
  if (shifts.empty()) return std::nullopt;
  std::nth_element(shifts.begin(), shifts.begin() + shifts.size() / 2, shifts.end());
  return static_cast<float>(shifts[shifts.size() / 2]);
}

}  // namespace

std::vector<Eigen::Isometry3d> SubmapBuilder::optimize_keyframes(const Eigen::Isometry3d& T_odom_submap,
                                                                 std::optional<float>& noise) {
  const int n = static_cast<int>(open_.size());
  Values local;
  for (int k = 0; k < n; ++k) local[k] = T_odom_submap.inverse() * open_[k].T_odom;
  if (n >= 2) {
    // Fully connected: every keyframe pair gets a VGICP factor (source later, target earlier).
    Stopwatch w;
    FactorGraph g;
    std::vector<std::shared_ptr<Factor>> consecutive;
    for (int b = 1; b < n; ++b) {
      auto source = config_.factor_source_points > 0
                        ? std::make_shared<const PointCloud>(evenly_subsampled(*open_[b].cloud, config_.factor_source_points))
                        : open_[b].cloud;
      for (int a = 0; a < b; ++a) {
        auto f = std::make_shared<MatchingCostFactor>(b, a, source, open_[a].voxels, TrialVoxels::kept);
        f->set_robust_width(static_cast<float>(config_.robust_width));
        if (a == b - 1) consecutive.push_back(f);
        g.add(std::move(f));
      }
    }
    add_gyro_factors(g);
    stats_.factors.add(w.lap_ms());
    LMConfig lc;
    lc.max_iterations = config_.max_iterations;
    lc.relative_error_tol = config_.relative_error_tol;
    LevenbergMarquardt(lc, backend_).optimize(g, local, {0});
    noise = keyframe_noise(consecutive, local);
    stats_.optimization.add(w.lap_ms());
  }
  std::vector<Eigen::Isometry3d> out;
  for (int k = 0; k < n; ++k) out.push_back(local.at(k));
  return out;
}

// The gyro's rotation between consecutive keyframes: the matching costs of sparse sweeps that
// overlap almost entirely turn them against each other by tenths of a degree, where the gyro is
// off by hundredths. With the LiDAR-inertial state, its translation joins them
// (local.inertial_translation_sigma): a corridor's keyframes slid by metres where the matching
// costs could not see along it.
void SubmapBuilder::add_gyro_factors(FactorGraph& graph) {
  if (!(config_.gyro_weight > 0.0)) return;
  for (size_t b = 1; b < open_.size(); ++b) {
    if (!open_[b].gyro || !(open_[b].gyro->variance > 0.0)) continue;
    GyroRotation weighted = *open_[b].gyro;
    weighted.variance /= config_.gyro_weight;
    const int i = static_cast<int>(b) - 1, j = static_cast<int>(b);
    if (config_.inertial_translation_sigma > 0.0) {
      const Eigen::Vector3d t_i_j = (open_[i].T_odom.inverse() * open_[j].T_odom).translation();
      graph.add(gyro_motion_factor(i, j, weighted, t_i_j, config_.inertial_translation_sigma));
    } else {
      graph.add(gyro_rotation_factor(i, j, weighted));
    }
    ++stats_.gyro_factors;
  }
}

void SubmapBuilder::drop_gyro() {
  for (Keyframe& k : open_) k.gyro.reset();
  since_keyframe_.reset();
}

std::optional<Submap> SubmapBuilder::close() {
  complete_ = false;
  if (open_.empty()) return std::nullopt;
  Submap s;
  s.id = next_id_++;
  s.T_odom = open_.front().T_odom;
  s.T_submap_keyframe = optimize_keyframes(s.T_odom, s.keyframe_noise);
  for (Keyframe& k : open_) {
    s.keyframes.push_back(k.frame);
    if (loop_.enabled) s.descriptors.push_back(std::move(k.descriptor));
  }
  s = merge(std::move(s));
  open_.clear();
  return s;
}

// Keyframe clouds in the submap frame, voxel-averaged means and covariances, and intensities when
// every keyframe has them (for the map's outputs; registration reads only points and covariances).
Submap SubmapBuilder::merge(Submap s) const {
  const bool intensities = std::all_of(open_.begin(), open_.end(), [](const Keyframe& k) { return k.cloud->has_intensities(); });
  PointCloud merged;
  for (size_t k = 0; k < open_.size(); ++k) {
    const PointCloud c = transformed(*open_[k].cloud, s.T_submap_keyframe[k]);
    merged.points.insert(merged.points.end(), c.points.begin(), c.points.end());
    merged.covs.insert(merged.covs.end(), c.covs.begin(), c.covs.end());
    if (intensities) merged.intensities.insert(merged.intensities.end(), c.intensities.begin(), c.intensities.end());
  }
  merged = voxel_downsample(merged, config_.submap_downsample);
  merged = evenly_subsampled(std::move(merged), config_.max_submap_points);
  auto voxels = std::make_shared<GaussianVoxelMap>(global_.voxel_resolution);
  voxels->insert(merged);
  voxels->finalize();
  PointCloud source = evenly_subsampled(merged, global_.factor_source_points);
  std::vector<float>().swap(source.intensities);  // kept for the whole run: only what the factors read
  s.factor_source = std::make_shared<const PointCloud>(std::move(source));
  s.cloud = std::make_shared<const PointCloud>(std::move(merged));
  s.voxels = voxels;
  return s;
}

}  // namespace gcmap
