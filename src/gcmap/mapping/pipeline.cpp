#include "gcmap/mapping/pipeline.hpp"

#include <spdlog/spdlog.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_pipeline.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cmath>

#include "gcmap/core/error.hpp"
#include "gcmap/odometry/preprocess_scan.hpp"

namespace gcmap {

namespace {

// KITTI's HDL-64 scans need a 0.22 deg intrinsic elevation correction (as in CT-ICP/KISS-ICP).
void kitti_vertical_correction(PointCloud& c) {
  const double angle = 0.22 * M_PI / 180.0;
  for (auto& p : c.points) {
    const Eigen::Vector3d v = p.cast<double>();
    const Eigen::Vector3d axis = v.cross(Eigen::Vector3d::UnitZ());
    if (axis.norm() < 1e-9) continue;
    p = (Eigen::AngleAxisd(angle, axis.normalized()) * v).cast<float>();
  }
}

// SemanticKITTI moving classes (252-259, lower 16 bits of the label).
void remove_moving_labels(PointCloud& c) {
  std::vector<char> keep(c.size());
  for (size_t i = 0; i < c.size(); ++i) {
    const uint32_t cls = c.labels[i] & 0xffff;
    keep[i] = !(cls >= 252 && cls <= 259);
  }
  c.filter(keep);
}

}  // namespace

PipelineOptions with_elevation_calibration(PipelineOptions options, const PreprocessConfig& config) {
  if (!options.elevation_calibration && !config.elevation_calibration.empty())
    options.elevation_calibration =
        std::make_shared<const ElevationCalibration>(ElevationCalibration::load(config.elevation_calibration));
  return options;
}

void times_from_azimuth(PointCloud& cloud, const PreprocessConfig& config) {
  const double start = config.sweep_start_deg * M_PI / 180.0;
  // float(period * fraction) may round up to the period itself: the last float below it instead.
  const float last = std::nextafter(static_cast<float>(config.sweep_period), 0.f);
  cloud.times.resize(cloud.size());
  for (size_t i = 0; i < cloud.size(); ++i) {
    const Eigen::Vector3f& p = cloud.points[i];
    const double angle = std::atan2(static_cast<double>(p.y()), static_cast<double>(p.x())) - start;
    double fraction = (config.sweep_clockwise ? -angle : angle) / (2.0 * M_PI);
    fraction -= std::floor(fraction);
    cloud.times[i] = std::min(static_cast<float>(config.sweep_period * fraction), last);
  }
}

MappingPipeline::MappingPipeline(const MappingConfig& config, std::shared_ptr<LinearizationBackend> backend,
                                 PipelineOptions options)
    : config_(config),
      backend_(backend ? std::move(backend) : std::make_shared<CpuBackend>()),
      options_(with_elevation_calibration(std::move(options), config.preprocess)),
      odometry_(config.odometry, config.preprocess, config.imu, backend_),
      mapper_(config, backend_) {}

PreparedScan MappingPipeline::prepare(PointCloud raw, double stamp) const {
  PreparedScan out = prepare_scan(std::move(raw), stamp, config_.preprocess, options_, backend_.get());
  // Here, on any thread, rather than in the serial mapping stage, unless deskewing will change the cloud.
  if (out.cloud && !out.cloud->empty() && !(config_.preprocess.deskew && out.cloud->has_times())) {
    Stopwatch w;
    out.keyframe = keyframe_shape(*out.cloud, config_.local, config_.loop);
    out.preprocess_ms += w.ms();
  }
  return out;
}

PreparedScan prepare_scan(PointCloud raw, double stamp, const PreprocessConfig& config, const PipelineOptions& options,
                          LinearizationBackend* backend) {
  Stopwatch w;
  PreparedScan out;
  out.stamp = stamp;
  if (raw.has_times() && raw.times.size() != raw.size()) {
    spdlog::warn("scan at {:.6f} s: {} point times for {} points, ignored", stamp, raw.times.size(), raw.size());
    raw.times.clear();
  }
  if (raw.has_labels() && raw.labels.size() != raw.size()) {
    spdlog::warn("scan at {:.6f} s: {} labels for {} points, ignored", stamp, raw.labels.size(), raw.size());
    raw.labels.clear();
  }
  if (config.deskew_from_azimuth && !raw.has_times()) times_from_azimuth(raw, config);
  if (config.remove_dynamic_labels && raw.has_labels()) remove_moving_labels(raw);
  raw.labels.clear();  // not averaged per voxel: nothing downstream reads them
  if (options.kitti_hdl64 && config.kitti_vertical_correction) kitti_vertical_correction(raw);
  if (options.elevation_calibration) options.elevation_calibration->correct(raw);
  // Range filtering drops NaN points too; what is left of a NaN-only scan is empty (unusable).
  out.cloud = std::make_shared<PointCloud>(preprocess_scan(raw, config, backend));
  out.preprocess_ms = w.ms();
  return out;
}

void MappingPipeline::add_imu(const ImuSample& sample) {
  if (finished_) throw Error("add_imu: the pipeline is finished");
  if (!config_.imu.use) return;
  odometry_.add_imu(sample);
  mapper_.add_imu(sample);
  ++imu_samples_;
}

Frame MappingPipeline::add_scan(PointCloud scan, double stamp, std::optional<Eigen::Isometry3d> T_odom) {
  if (finished_) throw Error("add_scan: the pipeline is finished");
  if (!std::isfinite(stamp)) throw Error("add_scan: the stamp is not a finite number");
  return add_prepared(prepare(std::move(scan), stamp), T_odom);
}

Frame MappingPipeline::add_prepared(PreparedScan scan, std::optional<Eigen::Isometry3d> T_odom) {
  return map_frame(track_frame(std::move(scan), T_odom));
}

MappingPipeline::Tracked MappingPipeline::track_frame(PreparedScan scan, std::optional<Eigen::Isometry3d> T_odom) {
  if (finished_) throw Error("add_scan: the pipeline is finished");
  if (!stamps_.empty() && scan.stamp < stamps_.back())
    throw Error("add_scan: stamp " + std::to_string(scan.stamp) + " s is before the previous scan's " +
                std::to_string(stamps_.back()) + " s");
  Tracked t;
  Frame& f = t.frame;
  f.index = static_cast<int>(stamps_.size());
  f.stamp = scan.stamp;
  if (!scan.cloud) {
    spdlog::warn("skipping scan {}: {}", f.index, scan.error);
    ++unusable_scans_;
  }
  preprocess_ms_.add(scan.preprocess_ms);
  Stopwatch w;
  SweepEstimate e = odometry_.track(scan.cloud, scan.stamp, T_odom);
  f.T_odom = e.T_world_frame;
  f.deskewed = e.deskewed;
  f.odometry_failed = e.failed;
  f.registration = e.quality;
  f.deskew_shift = e.deskew_shift;
  gyro_deskewed_ += e.gyro ? 1 : 0;
  inertial_predicted_ += e.inertial ? 1 : 0;
  inertial_deskewed_ += e.inertial_motion ? 1 : 0;
  if (!gyro_warned_ && odometry_.gyro_rejected_at()) {
    spdlog::warn("scan {}: the gyro's rates do not follow the LiDAR's registered rotation: the IMU is no longer used "
                 "(check imu.roll_deg, pitch_deg and yaw_deg)",
                 f.index);
    gyro_warned_ = true;
    t.imu_rejected = true;
  }
  frame_figures_.push_back({e.quality, e.deskew_shift, scan.cloud != nullptr});
  if (e.revised) odometry_poses_[e.revised->frame] = e.revised->T_world_frame;
  if (f.odometry_failed) {
    spdlog::warn("scan {}: odometry failed ({}), placed by the prediction", f.index, to_string(e.quality.failure));
    ++odometry_failures_;
  }
  if (e.lost)
    spdlog::warn(
        "scan {}: odometry lost (scans in a row placed by the prediction): a new local model starts "
        "at the next scan",
        f.index);
  odometry_ms_.add(w.lap_ms());
  if (!stamps_.empty()) t.gyro = odometry_.gyro_rotation(stamps_.back(), scan.stamp);
  stamps_.push_back(scan.stamp);
  odometry_poses_.push_back(f.T_odom);
  f.points = scan.cloud ? scan.cloud->size() : 0;
  t.cloud = std::move(scan.cloud);
  if (!f.deskewed) t.keyframe = std::move(scan.keyframe);
  t.revised = std::move(e.revised);
  return t;
}

Frame MappingPipeline::map_frame(Tracked t) {
  Frame& f = t.frame;
  if (t.imu_rejected) mapper_.drop_imu();
  if (t.revised) mapper_.revise_frame(t.revised->frame, t.revised->cloud, t.revised->T_world_frame);
  const bool observed = !f.odometry_failed && (!f.registration.registered || f.registration.conditioning() >= kDegenerateConditioning);
  f.status = mapper_.add_frame(f.index, t.cloud, f.T_odom, std::move(t.keyframe), f.stamp, observed, t.gyro);
  if (f.status == FrameStatus::unusable && t.cloud) ++unusable_frames_;
  statuses_.push_back(f.status);
  f.T_world_frame = mapper_.frame_pose(f.index);
  return f;
}

void MappingPipeline::finish(std::optional<int> max_final_iterations, const IterationCallback& on_iteration) {
  if (finished_) return;
  mapper_.finish(max_final_iterations, on_iteration);
  finished_ = true;
  seconds_ = clock_.ms() / 1000.0;
}

PipelineStats MappingPipeline::stats() const {
  PipelineStats s;
  s.frames = stamps_.size();
  s.unusable = unusable_scans_ + unusable_frames_;
  s.odometry_failures = odometry_failures_;
  s.imu_samples = imu_samples_;
  s.gyro_deskewed = gyro_deskewed_;
  s.inertial_predicted = inertial_predicted_;
  s.inertial_deskewed = inertial_deskewed_;
  s.inertial_bias = odometry_.inertial_bias();
  s.inertial_gravity_turn_deg = odometry_.inertial_gravity_turn_deg();
  s.gyro_bias = odometry_.gyro_bias();
  s.imu_clock = odometry_.imu_clock_check();
  s.gyro_rejected_at = odometry_.gyro_rejected_at();
  s.deskew_gyro_noise = odometry_.deskew_gyro_noise();
  s.gravity = mapper_.gravity_stats();
  s.preprocess = preprocess_ms_;
  s.odometry = odometry_ms_;
  s.mapper = mapper_.stats();
  s.seconds = finished_ ? seconds_ : clock_.ms() / 1000.0;
  return s;
}

size_t MappingPipeline::run(ScanSource& source, const RunOptions& options) {
  mapper_.stop_on(options.stop);
  struct Item {
    int frame = 0;
    ScanRecord record;
    PreparedScan prepared;
    Tracked tracked;
  };
  int next = 0;
  size_t added = 0;
  bool ended = false;
  // The mapping stages alone cannot keep both cores busy (LM solves, assembly and voxel-map inserts
  // are serial), so scans are loaded and prepared ahead: 3 in flight on 2 cores, more where more
  // threads can prepare scans side by side (with a GPU, each mostly waits on its kernel).
  const size_t in_flight =
      std::max<size_t>(3, tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism) / 2);
  tbb::parallel_pipeline(in_flight,
                         tbb::make_filter<void, Item>(tbb::filter_mode::serial_in_order,
                                                      [&](tbb::flow_control& fc) {
                                                        Item item;
                                                        std::optional<ScanRecord> r;
                                                        if (!ended && !(options.stop && options.stop->load())) r = source.next();
                                                        if (!r) {
                                                          ended = true;
                                                          fc.stop();
                                                          return item;
                                                        }
                                                        item.frame = next++;
                                                        item.record = std::move(*r);
                                                        return item;
                                                      }) &
                             tbb::make_filter<Item, Item>(tbb::filter_mode::parallel,
                                                          [&](Item item) {
                                                            Stopwatch w;
                                                            try {
                                                              item.prepared = prepare(item.record.load(), item.record.stamp);
                                                            } catch (const Error& e) {
                                                              item.prepared.stamp = item.record.stamp;
                                                              item.prepared.error = e.what();
                                                              item.prepared.preprocess_ms = w.ms();
                                                            }
                                                            return item;
                                                          }) &
                             // Odometry and mapping are serial stages of their own: the odometry of one frame runs
                             // while the mapper takes the one before (the backends serve both at once). Each is
                             // isolated: while waiting for its own parallel loops, a stage must not pick up a scan
                             // being loaded and prepared (TBB lets a waiting thread steal any task), which would hold
                             // up the serial stages that bound the throughput.
                             tbb::make_filter<Item, Item>(tbb::filter_mode::serial_in_order,
                                                          [&](Item item) {
                                                            std::optional<Eigen::Isometry3d> guess;
                                                            if (options.initial_pose) guess = options.initial_pose(item.frame);
                                                            item.tracked = tbb::this_task_arena::isolate(
                                                                [&] { return track_frame(std::move(item.prepared), guess); });
                                                            return item;
                                                          }) &
                             tbb::make_filter<Item, void>(tbb::filter_mode::serial_in_order, [&](Item item) {
                               const Frame f = tbb::this_task_arena::isolate([&] { return map_frame(std::move(item.tracked)); });
                               ++added;
                               if (options.on_frame) options.on_frame(f);
                             }));
  return added;
}

}  // namespace gcmap
