#include "gcmap/mapping/mapper.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include "gcmap/core/error.hpp"
#include "gcmap/core/preprocess.hpp"
#include "gcmap/core/se3.hpp"

namespace gcmap {

namespace {
const MappingConfig& validated(const MappingConfig& config) {
  config.validate();
  return config;
}

// The odometry's translation is the LiDAR-inertial state's only with imu.inertial_odometry.
LocalMappingConfig local_config(const MappingConfig& config) {
  LocalMappingConfig local = config.local;
  if (!config.imu.inertial_odometry) local.inertial_translation_sigma = 0.0;
  return local;
}
}  // namespace

Mapper::Mapper(const MappingConfig& config, std::shared_ptr<LinearizationBackend> backend)
    : config_(validated(config)),
      backend_(backend ? std::move(backend) : std::make_shared<CpuBackend>()),
      local_(local_config(config_), config_.global, config_.loop, backend_),
      loops_(config_.loop),
      global_(config_.global, config_.loop, backend_, config_.gnss, config_.imu) {}

FrameStatus Mapper::add_frame(int frame, const std::shared_ptr<const PointCloud>& cloud, const Eigen::Isometry3d& T_odom,
                              std::optional<KeyframeShape> shape, double stamp, bool observed,
                              const std::optional<GyroRotation>& gyro) {
  if (frame != static_cast<int>(frames_.size())) throw Error("Mapper: frames must be numbered consecutively from 0");
  if (!fixes_.empty() && !stamps_.empty() && stamp < stamps_.back())
    throw Error("Mapper: frame " + std::to_string(frame) + "'s stamp is before the previous frame's");
  frames_.push_back({-1, T_odom, -1, -1, observed, gyro});
  stamps_.push_back(stamp);
  SubmapBuilder::Result r = local_.add_frame(frame, cloud, T_odom, std::move(shape), gyro);
  frames_.back().anchor = r.anchor;
  if (r.closed) insert(std::move(*r.closed));
  return r.status;
}

bool Mapper::revise_frame(int frame, const std::shared_ptr<const PointCloud>& cloud, const Eigen::Isometry3d& T_odom) {
  if (frame < 0 || frame >= static_cast<int>(frames_.size())) throw Error("Mapper: revise_frame of an unknown frame");
  if (frames_[frame].submap >= 0) return false;
  frames_[frame].T_odom = T_odom;
  return local_.revise(frame, cloud, T_odom);
}

void Mapper::insert(Submap submap) {
  for (size_t k = 0; k < submap.keyframes.size(); ++k) {
    frames_[submap.keyframes[k]].submap = submap.id;
    frames_[submap.keyframes[k]].index = static_cast<int>(k);
  }
  loops_.add_submap(submap);
  std::vector<GnssMeasurement> fixes = place_fixes(submap);
  std::optional<GravityWindow> gravity = gravity_window(submap);
  std::optional<GyroRotation> gyro = gyro_between_submaps(submap);
  global_.insert(std::move(submap), &loops_, std::move(fixes), gravity, gyro);
}

void Mapper::add_imu(const ImuSample& sample) {
  if (!config_.imu.use || !config_.imu.level_map || gravity_dropped_) return;
  ImuSample s = sample;
  s.stamp -= config_.imu.time_offset;
  if (!imu_.empty() && !(s.stamp > imu_.back().stamp)) throw Error("Mapper: IMU stamps must increase");
  imu_.push_back(s);
}

void Mapper::drop_imu() {
  gravity_dropped_ = true;
  imu_.clear();
  for (FrameRecord& f : frames_) f.gyro.reset();
  local_.drop_gyro();
  global_.drop_imu();
}

std::optional<GyroRotation> Mapper::gyro_between_submaps(const Submap& inserting) const {
  if (inserting.id == 0 || submaps().empty()) return std::nullopt;
  GyroRotation chain;
  for (int f = submaps().back().keyframes.front() + 1; f <= inserting.keyframes.front(); ++f) {
    if (!frames_[f].gyro) return std::nullopt;
    chain = chain.then(*frames_[f].gyro);
  }
  return chain;
}

namespace {
// The gravity window's length (s): its error is that of three positions over its length, so a
// longer window sees gravity better, as long as the odometry holds its positions over it.
constexpr double kGravityWindow = 4.0;
}  // namespace

std::optional<GravityWindow> Mapper::gravity_window(const Submap& inserting) {
  if (imu_.empty() || frames_.size() < 3) return std::nullopt;
  const size_t b = frames_.size() - 1;
  size_t a = b;
  while (a > 0 && stamps_[b] - stamps_[a - 1] <= kGravityWindow) --a;
  size_t m = a;
  while (m + 1 < b && stamps_[m + 1] - stamps_[a] <= stamps_[b] - stamps_[m + 1]) ++m;
  if (b - a < 2 || m == a) return std::nullopt;
  // A tunnel's positions along it are the IMU's own (odometry/inertial_track.hpp): gravity read from
  // them would only echo the IMU's errors, and the bias came out at metres per second squared.
  for (size_t k = a; k <= b; ++k)
    if (!frames_[k].observed) return std::nullopt;
  std::vector<OdometryFrame> window;
  for (size_t k = a; k <= b; ++k) window.push_back({stamps_[k], frames_[k].T_odom});
  std::optional<GravityWindow> w =
      gcmap::gravity_window(imu_, window, 0, m - a, b - a, config_.imu, inserting.T_odom);
  if (w) w->submap = inserting.id;
  const auto keep = std::lower_bound(imu_.begin(), imu_.end(), stamps_[a] - 1.0,
                                     [](const ImuSample& x, double t) { return x.stamp < t; });
  imu_.erase(imu_.begin(), keep);
  return w;
}

GravityStats Mapper::gravity_stats() const {
  GravityStats s;
  s.levelled = global_.levelled();
  s.accel_bias = global_.accel_bias();
  const auto& factors = global_.gravity_factors();
  s.windows = factors.size();
  double sum = 0.0;
  for (const auto& f : factors) {
    s.downweighted += f->weight() < 1.0;
    sum += std::pow(f->tilt(global_.pose(f->keys()[0]), global_.accel_bias_pose()), 2);
  }
  if (!factors.empty()) s.rms_tilt_deg = std::sqrt(sum / double(factors.size())) * 180.0 / M_PI;
  return s;
}

void Mapper::set_gnss(std::vector<GnssPosition> fixes) {
  if (!frames_.empty()) throw Error("Mapper: set_gnss before the first frame");
  for (size_t k = 1; k < fixes.size(); ++k)
    if (!(fixes[k].stamp > fixes[k - 1].stamp)) throw Error("Mapper: GNSS stamps must increase");
  fixes_ = std::move(fixes);
}

std::optional<std::pair<int, Eigen::Isometry3d>> Mapper::in_submap(int f, const Submap& inserting) const {
  const int anchor = frames_[f].anchor;
  if (anchor < 0 || frames_[anchor].submap < 0) return std::nullopt;
  const FrameRecord& a = frames_[anchor];
  const Submap& s = a.submap == inserting.id ? inserting : submaps()[a.submap];
  return std::make_pair(a.submap, s.T_submap_keyframe[a.index] * a.T_odom.inverse() * frames_[f].T_odom);
}

namespace {
// The pose a fraction `alpha` of the way along `T` (slerp, straight translation).
Eigen::Isometry3d partway(const Eigen::Isometry3d& T, double alpha) {
  Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
  out.linear() = Eigen::Quaterniond::Identity().slerp(alpha, Eigen::Quaterniond(T.linear())).toRotationMatrix();
  out.translation() = alpha * T.translation();
  return out;
}
}  // namespace

std::vector<GnssMeasurement> Mapper::place_fixes(const Submap& inserting) {
  std::vector<GnssMeasurement> out;
  const Eigen::Vector3d lever(config_.gnss.lever_arm_x, config_.gnss.lever_arm_y, config_.gnss.lever_arm_z);
  for (; next_fix_ < fixes_.size(); ++next_fix_) {
    const GnssPosition& fix = fixes_[next_fix_];
    // f0: the last frame at or before the fix, f1 the one after it (the fix needs both, unless on f0).
    const int f0 = static_cast<int>(std::upper_bound(stamps_.begin(), stamps_.end(), fix.stamp) - stamps_.begin()) - 1;
    if (f0 < 0) {
      ++fixes_outside_;
      continue;
    }
    const bool on_f0 = stamps_[f0] == fix.stamp, have_f1 = f0 + 1 < static_cast<int>(stamps_.size());
    const auto placed = in_submap(f0, inserting);
    if (!placed || (!on_f0 && !have_f1)) break;  // later: its frames are not all mapped yet
    if (!on_f0 && stamps_[f0 + 1] - stamps_[f0] > config_.gnss.max_gap) {
      ++fixes_gaps_;
      continue;
    }
    const double alpha = on_f0 ? 0.0 : (fix.stamp - stamps_[f0]) / (stamps_[f0 + 1] - stamps_[f0]);
    const Eigen::Isometry3d T_f0_fix =
        on_f0 ? Eigen::Isometry3d::Identity() : partway(frames_[f0].T_odom.inverse() * frames_[f0 + 1].T_odom, alpha);
    out.push_back({placed->first, next_fix_, placed->second * T_f0_fix * lever, fix.p_enu, fix.sigma});
  }
  return out;
}

GnssStats Mapper::gnss_stats() const {
  GnssStats s;
  s.fixes = fixes_.size();
  s.outside = fixes_outside_ + (fixes_.size() - next_fix_);
  s.gaps = fixes_gaps_;
  s.waiting = global_.gnss_waiting();
  s.georeferenced = global_.georeferenced();
  const auto& factors = global_.gnss_factors();
  s.used = factors.size();
  double sum = 0.0;
  for (const auto& f : factors) {
    const Eigen::Isometry3d& T = global_.pose(f->keys()[0]);
    if (f->whitened_norm(T) > config_.gnss.outlier_threshold) ++s.rejected;
    else sum += f->residual(T).squaredNorm();
    s.downweighted += f->weight() < 1.0;
  }
  if (s.used > s.rejected) s.rms_residual = std::sqrt(sum / double(s.used - s.rejected));
  return s;
}

void Mapper::finish(std::optional<int> max_final_iterations, const IterationCallback& on_iteration) {
  if (auto s = local_.close()) insert(std::move(*s));
  global_.optimize_final(max_final_iterations, on_iteration);
}

Eigen::Isometry3d Mapper::keyframe_world(int kf) const {
  const FrameRecord& r = frames_[kf];
  if (r.submap >= 0) return global_.pose(r.submap) * submaps()[r.submap].T_submap_keyframe[r.index];
  // A keyframe of the open submap (only before finish()): placed from the last submap by odometry.
  if (submaps().empty()) return r.T_odom;
  const Submap& last = submaps().back();
  return global_.pose(last.id) * last.T_odom.inverse() * r.T_odom;
}

Eigen::Isometry3d Mapper::world_pose(int f) const {
  const int anchor = frames_[f].anchor;
  if (anchor < 0) return frames_[f].T_odom;
  return keyframe_world(anchor) * frames_[anchor].T_odom.inverse() * frames_[f].T_odom;
}

Eigen::Isometry3d Mapper::output_from_world() const {
  // Georeferenced: the world is the local ENU frame, and so is the output.
  if (global_.georeferenced()) return Eigen::Isometry3d::Identity();
  if (frames_.empty()) return Eigen::Isometry3d::Identity();
  if (!global_.levelled()) return world_pose(0).inverse();
  // Levelled: the first frame's position and heading, with the world's z.
  const Eigen::Isometry3d T0 = world_pose(0);
  Eigen::Vector3d heading = T0.linear().col(0);
  heading.z() = 0.0;
  Eigen::Isometry3d T_world_out = Eigen::Isometry3d::Identity();
  T_world_out.linear() = Eigen::AngleAxisd(std::atan2(heading.y(), heading.x()), Eigen::Vector3d::UnitZ()).toRotationMatrix();
  T_world_out.translation() = T0.translation();
  return T_world_out.inverse();
}

Eigen::Isometry3d Mapper::frame_pose(int frame) const { return normalized(output_from_world() * world_pose(frame)); }

std::pair<std::vector<Eigen::Isometry3d>, RotationSmoothing> Mapper::smoothed_trajectory() const {
  const Eigen::Isometry3d T0_inv = output_from_world();
  std::vector<Eigen::Isometry3d> out(frames_.size());
  std::vector<std::optional<GyroRotation>> gyro(frames_.size());
  for (size_t f = 0; f < frames_.size(); ++f) {
    out[f] = normalized(T0_inv * world_pose(static_cast<int>(f)));
    gyro[f] = frames_[f].gyro;
  }
  RotationSmoothing smoothing;
  if (config_.imu.use && config_.imu.smooth_rotations) smoothing = smooth_rotations(out, gyro);
  return {std::move(out), smoothing};
}

namespace {

struct Placement {
  Eigen::Matrix3f R;
  Eigen::Vector3f t;
};

// One compiled transform for every pass: a point's slab must not depend on how a pass was inlined
// (-march=native contracts multiply-adds differently per call site).
[[gnu::noinline]] void place(const Placement& T, const Eigen::Vector3f* in, size_t n, Eigen::Vector3f* out) {
  for (size_t i = 0; i < n; ++i) out[i] = T.R * in[i] + T.t;
}

// The map is assembled in slabs of voxel columns along x (a voxel never straddles two), so the
// transient is a block's points, not the whole drive's. voxel_downsample orders voxels by (x, y, z)
// and sums each in index order, so concatenated slabs equal one downsample of everything.
class SlabAssembler {
 public:
  SlabAssembler(const std::vector<Submap>& submaps, const std::vector<Eigen::Isometry3d>& placements, double resolution)
      : submaps_(submaps), inv_(1.0 / resolution), resolution_(resolution), intensities_(have_intensities(submaps)) {
    for (const Eigen::Isometry3d& T : placements) placed_.push_back({T.linear().cast<float>(), T.translation().cast<float>()});
  }

  PointCloud assemble(size_t block_points) {
    if (!histogram()) return PointCloud{};
    std::vector<PointCloud> slabs;
    size_t total = 0;
    for (size_t begin = 0; begin < counts_.size();) {
      size_t end = begin, n = 0;
      while (end < counts_.size() && (n == 0 || n + counts_[end] <= block_points)) n += counts_[end++];
      slabs.push_back(voxel_downsample(gather(begin, end, n), resolution_));
      total += slabs.back().size();
      begin = end;
    }
    PointCloud map;
    map.points.reserve(total);
    if (intensities_) map.intensities.reserve(total);
    for (const PointCloud& slab : slabs) {
      map.points.insert(map.points.end(), slab.points.begin(), slab.points.end());
      map.intensities.insert(map.intensities.end(), slab.intensities.begin(), slab.intensities.end());
    }
    return map;
  }

 private:
  // The x voxel column, floored as voxel_downsample floors it.
  int64_t column(float x) const { return static_cast<int64_t>(std::floor(static_cast<double>(x) * inv_)); }
  size_t bin(float x) const { return static_cast<size_t>((column(x) - lo_) >> shift_); }

  template <typename Fn>
  void for_each_point(size_t s, Fn&& fn) const {
    std::array<Eigen::Vector3f, 256> placed;
    const std::vector<Eigen::Vector3f>& points = submaps_[s].cloud->points;
    for (size_t b = 0; b < points.size(); b += placed.size()) {
      const size_t n = std::min(placed.size(), points.size() - b);
      place(placed_[s], points.data() + b, n, placed.data());
      for (size_t i = 0; i < n; ++i) fn(placed[i], b + i);
    }
  }

  // Points per column bin (columns coarsened to at most 2^20 bins); false without points.
  bool histogram() {
    lo_ = std::numeric_limits<int64_t>::max();
    int64_t hi = std::numeric_limits<int64_t>::min();
    for (size_t s = 0; s < submaps_.size(); ++s)
      for_each_point(s, [&](const Eigen::Vector3f& q, size_t) {
        lo_ = std::min(lo_, column(q.x()));
        hi = std::max(hi, column(q.x()));
      });
    if (hi < lo_) return false;
    while (((hi - lo_) >> shift_) >= (int64_t{1} << 20)) ++shift_;
    counts_.assign(static_cast<size_t>((hi - lo_) >> shift_) + 1, 0);
    for (size_t s = 0; s < submaps_.size(); ++s)
      for_each_point(s, [&](const Eigen::Vector3f& q, size_t) { ++counts_[bin(q.x())]; });
    return true;
  }

  // The n points in bins [begin, end), in submap order.
  PointCloud gather(size_t begin, size_t end, size_t n) const {
    std::vector<size_t> offsets(submaps_.size() + 1, 0);
    tbb::parallel_for(size_t{0}, submaps_.size(), [&](size_t s) {
      for_each_point(s, [&](const Eigen::Vector3f& q, size_t) { offsets[s + 1] += bin(q.x()) - begin < end - begin; });
    });
    for (size_t s = 0; s < submaps_.size(); ++s) offsets[s + 1] += offsets[s];
    if (offsets.back() != n) throw Error("assemble_map: a slab's points were counted differently");
    PointCloud slab;
    slab.points.resize(n);
    if (intensities_) slab.intensities.resize(n);
    tbb::parallel_for(size_t{0}, submaps_.size(), [&](size_t s) {
      size_t k = offsets[s];
      for_each_point(s, [&](const Eigen::Vector3f& q, size_t i) {
        if (bin(q.x()) - begin >= end - begin) return;
        if (intensities_) slab.intensities[k] = submaps_[s].cloud->intensities[i];
        slab.points[k++] = q;
      });
    });
    return slab;
  }

  const std::vector<Submap>& submaps_;
  std::vector<Placement> placed_;
  double inv_, resolution_;
  int64_t lo_ = 0;
  int shift_ = 0;
  bool intensities_ = false;
  std::vector<size_t> counts_;
};

}  // namespace

bool have_intensities(const std::vector<Submap>& submaps) {
  return std::all_of(submaps.begin(), submaps.end(),
                     [](const Submap& s) { return s.cloud->empty() || s.cloud->has_intensities(); });
}

PointCloud assemble_map(const std::vector<Submap>& submaps, const std::vector<Eigen::Isometry3d>& T_out_submap, double resolution,
                        size_t block_points) {
  if (!(resolution > 0.0)) throw Error("assemble_map: resolution must be positive");
  if (T_out_submap.size() != submaps.size()) throw Error("assemble_map: a pose per submap is needed");
  return SlabAssembler(submaps, T_out_submap, resolution).assemble(std::max<size_t>(block_points, 1));
}

PointCloud Mapper::assemble_map(double resolution, size_t block_points) const {
  // Points (and intensities) in the output frame (first frame identity, like the trajectory).
  Eigen::Isometry3d T_out_world = Eigen::Isometry3d::Identity();
  if (global_.georeferenced() || global_.levelled()) T_out_world = output_from_world();
  else if (!frames_.empty() && frames_[0].submap >= 0) T_out_world = keyframe_world(0).inverse();
  std::vector<Eigen::Isometry3d> placements;
  for (const Submap& s : submaps()) placements.push_back(T_out_world * global_.pose(s.id));
  return gcmap::assemble_map(submaps(), placements, resolution, block_points);
}

}  // namespace gcmap
