#include "gcmap/mapping/global_mapper.hpp"

#include <tbb/parallel_for.h>

#include <Eigen/Eigenvalues>
#include <algorithm>

#include "gcmap/core/error.hpp"
#include "gcmap/loop/loop_closure.hpp"
#include "gcmap/registration/gicp.hpp"
#include "gcmap/registration/registration.hpp"
#include "gcmap/registration/vgicp.hpp"

namespace gcmap {

const char* to_string(FactorKind kind) {
  switch (kind) {
    case FactorKind::matching_cost: return "matching_cost";
    case FactorKind::odometry: return "odometry";
    case FactorKind::se3: return "se3";
    case FactorKind::loop: return "loop";
  }
  return "?";
}

namespace {
LMConfig lm_config(const GlobalMappingConfig& global, int iterations, double relative_error_tol = LMConfig{}.relative_error_tol) {
  LMConfig c;
  c.max_iterations = iterations;
  c.relative_error_tol = relative_error_tol;
  c.linear_solver = global.linear_solver;
  return c;
}
}  // namespace

namespace {
// Weighted yaw and translation (the 2-D Procrustes solution, z by the weighted mean) over `in`.
Eigen::Isometry3d yaw_translation(const std::vector<Eigen::Vector3d>& a, const std::vector<Eigen::Vector3d>& b,
                                  const std::vector<double>& w, const std::vector<char>& in) {
  Eigen::Vector3d ca = Eigen::Vector3d::Zero(), cb = Eigen::Vector3d::Zero();
  double sum = 0.0;
  for (size_t i = 0; i < a.size(); ++i) {
    if (!in[i]) continue;
    ca += w[i] * a[i];
    cb += w[i] * b[i];
    sum += w[i];
  }
  ca /= sum;
  cb /= sum;
  double dot = 0.0, cross = 0.0;
  for (size_t i = 0; i < a.size(); ++i) {
    if (!in[i]) continue;
    const Eigen::Vector3d p = a[i] - ca, q = b[i] - cb;
    dot += w[i] * (p.x() * q.x() + p.y() * q.y());
    cross += w[i] * (p.x() * q.y() - p.y() * q.x());
  }
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(std::atan2(cross, dot), Eigen::Vector3d::UnitZ()).toRotationMatrix();
  T.translation() = cb - T.linear() * ca;
  return T;
}
}  // namespace

Eigen::Isometry3d fit_yaw_translation(const std::vector<Eigen::Vector3d>& world, const std::vector<Eigen::Vector3d>& enu,
                                      const std::vector<double>& weights, std::vector<char>* inliers) {
  if (world.size() != enu.size() || world.size() != weights.size() || world.size() < 2)
    throw Error("fit_yaw_translation: needs at least 2 pairs of points with a weight each");
  std::vector<char> in(world.size(), 1);
  Eigen::Isometry3d T = yaw_translation(world, enu, weights, in);
  for (int pass = 0; pass < 2; ++pass) {
    std::vector<double> r(world.size());
    for (size_t i = 0; i < world.size(); ++i) r[i] = (T * world[i] - enu[i]).norm();
    std::vector<double> sorted = r;
    std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
    const double bound = std::max(4.0 * sorted[sorted.size() / 2], 0.5);
    for (size_t i = 0; i < world.size(); ++i) in[i] = r[i] <= bound;
    T = yaw_translation(world, enu, weights, in);
  }
  if (inliers) *inliers = in;
  return T;
}

Matrix6d odometry_factor_information() {
  Matrix6d info = Matrix6d::Identity();
  info.diagonal() << 1e4, 1e4, 1e4, 1e3, 1e3, 1e3;
  return info;
}

GlobalMapper::GlobalMapper(const GlobalMappingConfig& config, const LoopConfig& loop,
                           std::shared_ptr<LinearizationBackend> backend, const GnssConfig& gnss, const ImuConfig& imu)
    : config_(config),
      loop_(loop),
      gnss_(gnss),
      imu_(imu),
      backend_(std::move(backend)),
      lazy_(config.relinearize == Relinearize::moved ? std::make_shared<LazyBackend>(backend_, config.relinearize_threshold)
                                                     : nullptr),
      lm_(lm_config(config, config.max_iterations, config.relative_error_tol), lm_backend()) {
  if (lazy_) lazy_->set_max_relinearizations(static_cast<size_t>(config.max_relinearizations));
}

std::shared_ptr<LinearizationBackend> GlobalMapper::lm_backend() const {
  return lazy_ ? std::static_pointer_cast<LinearizationBackend>(lazy_) : backend_;
}

void GlobalMapper::count_linearizations() {
  if (!lazy_) return;
  stats_.factor_linearizations = lazy_->linearized();
  stats_.factor_reuses = lazy_->reused();
  stats_.factor_deferrals = lazy_->deferred();
}

void GlobalMapper::add_factor(GlobalFactor f) {
  // An explicit loop leaves its target open to the matching-cost factor of the implicit closure.
  if (f.kind != FactorKind::loop) connected_[f.target] = 1;
  factors_.push_back(std::move(f));
}

void GlobalMapper::add_unary(FactorGraph& g) const {
  for (const auto& f : gnss_factors_) g.add(f);
  for (const auto& f : gravity_factors_) g.add(f);
  for (const auto& f : gyro_factors_) g.add(f);
  if (accel_bias_prior_) g.add(accel_bias_prior_);
  if (gauge_ && !georeferenced_) g.add(gauge_);
}

FactorGraph GlobalMapper::graph() const {
  FactorGraph g;
  for (const GlobalFactor& f : factors_) g.add(f.factor);
  add_unary(g);
  return g;
}

namespace {
// How far a window's gravity may stray (in its sigmas) before it counts less: an odometry failure
// inside a window puts its positions, and so its gravity, wrong.
constexpr double kGravityHuber = 3.0;
// The prior on the accelerometer's bias (m/s^2): a MEMS IMU after its factory calibration.
constexpr double kAccelBiasPrior = 0.1;
// The hold on submap 0's position and heading once roll and pitch are free (m, and the sine of the heading).
constexpr double kGaugeSigma = 1e-4;
}  // namespace

void GlobalMapper::level_world(const Eigen::Vector3d& up_world) {
  const Eigen::Isometry3d R_level(Eigen::Quaterniond::FromTwoVectors(up_world, Eigen::Vector3d::UnitZ()));
  for (auto& [key, T] : values_)  // about submap 0's origin, the world origin
    if (key != kAccelBiasKey) T = normalized(R_level * T);
  gauge_ = std::make_shared<HeadingPositionFactor>(0, values_.at(0), kGaugeSigma);
}

void GlobalMapper::take_gravity(const GravityWindow& window) {
  if (!gauge_ && !georeferenced_) level_world(values_.at(window.submap).linear() * window.up(Eigen::Vector3d::Zero()));
  if (!accel_bias_prior_) {
    values_[kAccelBiasKey] = Eigen::Isometry3d::Identity();
    accel_bias_prior_ = std::make_shared<AccelBiasPriorFactor>(kAccelBiasKey, kAccelBiasPrior);
  }
  gravity_factors_.push_back(
      std::make_shared<GravityFactor>(window, kAccelBiasKey, imu_.gravity, RobustKernel::huber(kGravityHuber)));
}

Eigen::Vector3d GlobalMapper::accel_bias() const {
  const auto it = values_.find(kAccelBiasKey);
  if (it == values_.end()) return Eigen::Vector3d::Zero();
  return it->second.translation();
}

void GlobalMapper::drop_imu() {
  gravity_factors_.clear();
  gyro_factors_.clear();
  accel_bias_prior_.reset();
  gauge_.reset();
  values_.erase(kAccelBiasKey);
}

void GlobalMapper::add_gnss_factor(const GnssMeasurement& m) {
  gnss_factors_.push_back(std::make_shared<GnssPositionFactor>(m.submap, m.p_submap_antenna, m.p_enu, m.sigma,
                                                               RobustKernel::huber(gnss_.huber_width)));
  gnss_used_.push_back(m);
}

void GlobalMapper::take_gnss(std::vector<GnssMeasurement> gnss) {
  if (georeferenced_) {
    for (const GnssMeasurement& m : gnss) add_gnss_factor(m);
    return;
  }
  gnss_pending_.insert(gnss_pending_.end(), gnss.begin(), gnss.end());
  if (!try_georeference()) return;
  for (const GnssMeasurement& m : gnss_pending_) add_gnss_factor(m);
  gnss_pending_.clear();
}

namespace {
// RMS distance of the points from their horizontal principal line: while the fixes lie along one
// line, a rotation of the map about it changes none of them, and a graph without a held pose would
// turn freely about it.
double lateral_spread(const std::vector<Eigen::Vector3d>& p) {
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (const Eigen::Vector3d& x : p) mean += x.head<2>() / double(p.size());
  Eigen::Matrix2d C = Eigen::Matrix2d::Zero();
  for (const Eigen::Vector3d& x : p) C += (x.head<2>() - mean) * (x.head<2>() - mean).transpose() / double(p.size());
  return std::sqrt(std::max(0.0, Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(C).eigenvalues()(0)));
}
}  // namespace

// The world so far is the first submap's frame, level as far as the sensor was at the start; a fit
// of yaw and translation turns it onto the fixes (roll and pitch are left to the factors). It waits
// until the fixes also spread across their main direction (align_distance / 6 RMS), so that the factors
// see every rotation once no pose is held.
bool GlobalMapper::try_georeference() {
  if (gnss_pending_.size() < 3) return false;
  std::vector<Eigen::Vector3d> world, enu;
  std::vector<double> weights;
  double extent = 0.0, sigma = 0.0;
  for (const GnssMeasurement& m : gnss_pending_) {
    world.push_back(values_.at(m.submap) * m.p_submap_antenna);
    enu.push_back(m.p_enu);
    weights.push_back(1.0 / m.sigma.head<2>().squaredNorm());
    extent = std::max(extent, (m.p_enu - gnss_pending_.front().p_enu).head<2>().norm());
    sigma += m.sigma.head<2>().norm() / gnss_pending_.size();
  }
  if (extent < std::max(gnss_.align_distance, 10.0 * sigma) ||
      lateral_spread(enu) < std::max(gnss_.align_distance / 6.0, 3.0 * sigma))
    return false;
  const Eigen::Isometry3d T_enu_world = fit_yaw_translation(world, enu, weights);
  for (auto& [key, T] : values_)
    if (key != kAccelBiasKey) T = normalized(T_enu_world * T);
  georeferenced_ = true;
  return true;
}

void GlobalMapper::insert(Submap s, LoopDetector* loops, std::vector<GnssMeasurement> gnss, std::optional<GravityWindow> gravity,
                          const std::optional<GyroRotation>& gyro) {
  const int id = s.id;
  if (id == 0) {
    values_[0] = Eigen::Isometry3d::Identity();
  } else {
    const Submap& prev = submaps_.back();
    values_[id] = values_.at(prev.id) * (prev.T_odom.inverse() * s.T_odom);
  }
  submaps_.push_back(std::move(s));
  const Submap& cur = submaps_.back();
  take_gnss(std::move(gnss));
  if (gravity) take_gravity(*gravity);
  if (gyro && id > 0) gyro_factors_.push_back(gyro_rotation_factor(id - 1, id, *gyro));
  if (id == 0) {
    stats_.per_submap.push_back({1, 0, 0.0, 0});
    return;
  }

  Stopwatch w;
  const int first = config_.mode == GlobalMode::sliding_window ? std::max(0, id - config_.window) : 0;
  connected_.assign(id, 0);
  if (connect_overlapping(id, first) == 0) {
    // Only where the submap would otherwise be disconnected.
    const Submap& prev = submaps_[id - 1];
    add_factor(
        {FactorKind::odometry, id, id - 1, 0.0,
         std::make_shared<RelativePoseFactor>(id - 1, id, prev.T_odom.inverse() * cur.T_odom, odometry_factor_information())});
  }
  stats_.factors.add(w.lap_ms());
  std::optional<LoopRecord> loop;
  if (loops && loop_.enabled && config_.mode == GlobalMode::full) loop = loops->detect(id, submaps_);
  if (loop)
    add_factor({FactorKind::loop, id, loop->target, 0.0, make_loop_factor(loop->target, id, loop->T_target_source, loop_)});
  w.lap_ms();  // loop time is counted in its own statistics
  // A verified loop says the estimate was off where it closes, so the revisit factors made at that
  // estimate may sit in a wrong minimum: the loop first steers without them.
  GlobalMappingStats::PerSubmap per{id + 1, 0, 0.0, 0};
  const size_t linearized_before = lazy_ ? lazy_->linearized() : 0;
  if (loop) optimize(without_revisit_factors(), per);
  optimize(graph(), per);
  double opt_ms = w.lap_ms();
  if (loop) {
    // The implicit loop closure: the corrected estimate now overlaps submaps it missed before.
    const int added = connect_overlapping(id, first);
    stats_.factors.add(w.lap_ms());
    if (added) optimize(graph(), per);
    opt_ms += w.lap_ms();
  }
  stats_.optimization.add(opt_ms);
  count_linearizations();
  per.num_factors = static_cast<int>(factors_.size());
  per.global_optimization_ms = opt_ms;
  stats_.linear_solver = lm_.active_solver();
  if (lazy_) per.linearized = lazy_->linearized() - linearized_before;
  stats_.per_submap.push_back(per);
}

void GlobalMapper::optimize(const FactorGraph& graph, GlobalMappingStats::PerSubmap& into) {
  const LMResult r = lm_.optimize(graph, values_, fixed());
  into.global_iterations += r.iterations;
  into.linearize_ms += r.linearize_ms;
  into.assemble_ms += r.assemble_ms;
  into.solve_ms += r.solve_ms;
}

FactorGraph GlobalMapper::without_revisit_factors() const {
  const auto revisit = [&](const GlobalFactor& f) {
    return f.kind != FactorKind::loop && f.kind != FactorKind::odometry && std::abs(f.source - f.target) > loop_.exclude_recent;
  };
  FactorGraph steer;
  std::vector<char> constrained(submaps_.size(), 0);
  for (const GlobalFactor& f : factors_) {
    if (revisit(f)) continue;
    steer.add(f.factor);
    constrained[f.source] = constrained[f.target] = 1;
  }
  add_unary(steer);
  // A submap held only by revisit factors keeps them (LM needs every pose constrained).
  for (const GlobalFactor& f : factors_)
    if (revisit(f) && (!constrained[f.source] || !constrained[f.target])) steer.add(f.factor);
  return steer;
}

std::vector<TargetOverlap> strongest_overlaps(std::vector<TargetOverlap> kept, const std::vector<int>& submaps, int keep, int n) {
  if (n <= 0 || kept.size() <= static_cast<size_t>(n)) return kept;
  const auto rank = [&](const TargetOverlap& t) { return std::pair(submaps[t.index] == keep, t.overlap); };
  std::vector<TargetOverlap> by_rank = kept;
  std::stable_sort(by_rank.begin(), by_rank.end(), [&](const auto& a, const auto& b) { return rank(a) > rank(b); });
  std::vector<char> chosen(submaps.size(), 0);
  for (int k = 0; k < n; ++k) chosen[by_rank[k].index] = 1;
  std::erase_if(kept, [&](const TargetOverlap& t) { return !chosen[t.index]; });
  return kept;
}

int GlobalMapper::connect_overlapping(int id, int first) {
  const Submap& cur = submaps_[id];
  std::vector<int> candidates;
  std::vector<std::shared_ptr<const GaussianVoxelMap>> targets;
  std::vector<Eigen::Isometry3d> T_target_source;
  for (int j = first; j < id; ++j) {
    if (connected_[j]) continue;
    candidates.push_back(j);
    targets.push_back(submaps_[j].voxels);
    T_target_source.push_back(values_.at(j).inverse() * values_.at(id));
  }
  const std::vector<TargetOverlap> kept =
      strongest_overlaps(overlapping_targets(*backend_, cur.factor_source, targets, T_target_source, config_.th_min), candidates,
                         id - 1, config_.max_new_factors);
  for (const TargetOverlap& t : kept) {
    const int j = candidates[t.index];
    if (config_.factor == FactorSource::se3) {
      // Ablation "Proposed (SE3)": a relative-pose constraint from kNN GICP scan matching with the
      // Hessian as information and a Huber kernel.
      const GicpTarget target(submaps_[j].cloud);
      const RegistrationResult r = align_gicp(*cur.cloud, target, values_.at(j).inverse() * values_.at(id));
      add_factor({FactorKind::se3, id, j, t.overlap,
                  std::make_shared<RelativePoseFactor>(j, id, r.T_target_source, r.H, RobustKernel::huber(10.0))});
    } else {
      auto f =
          std::make_shared<MatchingCostFactor>(id, j, cur.factor_source, submaps_[j].voxels, TrialVoxels::kept_per_optimization);
      f->set_min_conditioning(config_.min_conditioning);
      f->set_robust_width(static_cast<float>(config_.robust_width));
      add_factor({FactorKind::matching_cost, id, j, t.overlap, std::move(f)});
    }
  }
  return static_cast<int>(kept.size());
}

void GlobalMapper::optimize_final(std::optional<int> max_iterations, const IterationCallback& on_iteration) {
  const int iterations = max_iterations ? std::min(*max_iterations, config_.final_iterations) : config_.final_iterations;
  if ((factors_.empty() && gnss_factors_.empty() && gravity_factors_.empty() && gyro_factors_.empty()) || iterations <= 0) return;
  LevenbergMarquardt final_lm(lm_config(config_, iterations), lm_backend());
  final_lm.on_iteration(on_iteration);
  if (lazy_) lazy_->set_max_relinearizations(0);  // what insertions deferred is caught up here
  Stopwatch w;
  stats_.final_iterations = final_lm.optimize(graph(), values_, fixed()).iterations;
  stats_.final_optimization_ms = w.ms();
  stats_.optimization.add(stats_.final_optimization_ms);
  if (lazy_) lazy_->set_max_relinearizations(static_cast<size_t>(config_.max_relinearizations));
  count_linearizations();
}

std::vector<FactorEvaluation> GlobalMapper::evaluate_factors() const {
  std::vector<FactorEvaluation> out(factors_.size());
  tbb::parallel_for(size_t{0}, factors_.size(), [&](size_t f) {
    const Factor& factor = *factors_[f].factor;
    const Eigen::Isometry3d* poses[2] = {&values_.at(factor.keys()[0]), &values_.at(factor.keys()[1])};
    if (const auto* m = dynamic_cast<const MatchingCostFactor*>(&factor)) {
      const Eigen::Isometry3d T = poses[1]->inverse() * *poses[0];
      out[f].error = evaluate_vgicp(m->source(), m->target(), T, T, m->robust_width()).error;  // the cost optimized
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

}  // namespace gcmap
