#include "gcmap/mapping/self_calibration.hpp"

#include <tbb/parallel_for.h>
#include <tbb/parallel_pipeline.h>
#include <tbb/task_arena.h>

#include <cmath>
#include <cstdio>
#include <optional>

#include "gcmap/core/error.hpp"
#include "gcmap/odometry/sweep_odometry.hpp"

namespace gcmap {

namespace {

// What the odometry pass keeps: every n-th prepared scan as it was before the odometry deskewed it,
// and every frame's pose and stamp.
struct OdometryPass {
  std::vector<Eigen::Isometry3d> poses;
  std::vector<double> stamps;
  std::vector<std::pair<int, PointCloud>> kept;
};

struct Item {
  int frame = 0;
  ScanRecord record;
  std::shared_ptr<PointCloud> cloud;  // null: unusable
  std::optional<PointCloud> kept;
};

// The odometry takes the scan corrected by `options` and downsampled to calibration.downsample;
// the estimate every n-th one as it came, downsampled as the run does (coarser voxels mix beams).
void prepare_item(Item& item, const MappingConfig& config, const PipelineOptions& options) {
  PointCloud raw;
  try {
    raw = item.record.load();
  } catch (const Error&) {
    return;  // the run itself reports it
  }
  const double stamp = item.record.stamp;
  if (item.frame % config.calibration.every == 0) {
    const PipelineOptions as_it_came{.kitti_hdl64 = options.kitti_hdl64, .elevation_calibration = nullptr};
    PreparedScan p = prepare_scan(raw, stamp, config.preprocess, as_it_came);
    if (p.cloud && !p.cloud->empty()) item.kept = std::move(*p.cloud);
  }
  PreprocessConfig coarse = config.preprocess;
  coarse.downsample = std::max(coarse.downsample, config.calibration.downsample);
  PreparedScan p = prepare_scan(std::move(raw), stamp, coarse, options);
  if (p.cloud && !p.cloud->empty()) item.cloud = std::move(p.cloud);
}

OdometryPass run_odometry(ScanSource& source, const MappingConfig& config, const PipelineOptions& options,
                          const std::function<void(int)>& on_frame, int first_frame, const std::atomic<bool>* stop) {
  OdometryPass pass;
  SweepOdometry odometry(config.odometry, config.preprocess, ImuConfig{}, std::make_shared<CpuBackend>());
  int next = 0;
  tbb::parallel_pipeline(
      4,
      tbb::make_filter<void, Item>(tbb::filter_mode::serial_in_order,
                                   [&](tbb::flow_control& fc) {
                                     Item item;
                                     std::optional<ScanRecord> r;
                                     if (next < config.calibration.frames && !(stop && stop->load())) r = source.next();
                                     if (!r) {
                                       fc.stop();
                                       return item;
                                     }
                                     item.frame = next++;
                                     item.record = std::move(*r);
                                     return item;
                                   }) &
          tbb::make_filter<Item, Item>(tbb::filter_mode::parallel,
                                       [&](Item item) {
                                         prepare_item(item, config, options);
                                         return item;
                                       }) &
          tbb::make_filter<Item, void>(tbb::filter_mode::serial_in_order, [&](Item item) {
            const SweepEstimate e =
                tbb::this_task_arena::isolate([&] { return odometry.track(item.cloud, item.record.stamp); });
            pass.poses.push_back(e.T_world_frame);
            pass.stamps.push_back(item.record.stamp);
            if (e.revised) pass.poses[e.revised->frame] = e.revised->T_world_frame;
            if (item.kept) pass.kept.emplace_back(item.frame, std::move(*item.kept));
            if (on_frame) on_frame(first_frame + item.frame);
          }));
  return pass;
}

double travelled(const std::vector<Eigen::Isometry3d>& poses) {
  double d = 0.0;
  for (size_t i = 1; i < poses.size(); ++i) d += (poses[i].translation() - poses[i - 1].translation()).norm();
  return d;
}

// The kept scans deskewed by the motion from their frame to the next, placed on the trajectory.
std::vector<CalibrationScan> calibration_scans(OdometryPass& pass, bool deskew) {
  std::vector<CalibrationScan> scans(pass.kept.size());
  const int n = static_cast<int>(pass.poses.size());
  tbb::parallel_for(size_t{0}, scans.size(), [&](size_t k) {
    const int f = pass.kept[k].first, a = f + 1 < n ? f : f - 1;
    const double dt = a >= 0 ? pass.stamps[a + 1] - pass.stamps[a] : 0.0;
    Vector6d velocity = Vector6d::Zero();
    if (dt > 1e-6) velocity = se3_log(pass.poses[a].inverse() * pass.poses[a + 1]) / dt;
    scans[k] = calibration_scan(std::move(pass.kept[k].second), pass.poses[f], deskew && dt > 1e-6 ? &velocity : nullptr);
  });
  return scans;
}

std::string format(const char* pattern, auto... args) {
  char line[256];
  std::snprintf(line, sizeof line, pattern, args...);
  return line;
}

// Of the first scans that load (at most three), how many show rings, and how many were checked.
std::pair<int, int> scans_with_rings(ScanSource& source) {
  int checked = 0, with_rings = 0;
  for (int read = 0; checked < 3 && read < 10; ++read) {
    std::optional<ScanRecord> r = source.next();
    if (!r) break;
    try {
      with_rings += ElevationCalibration::has_rings(r->load());
      ++checked;
    } catch (const Error&) {}  // the run itself reports it
  }
  return {with_rings, checked};
}

// Offsets below calibration.min_offset_deg are dropped: on a sensor without bias the estimate
// still finds hundredths of a degree, and correcting by them costs accuracy. Null when none is left.
std::shared_ptr<const ElevationCalibration> estimate(OdometryPass& pass, const MappingConfig& config, int& scans_used) {
  std::vector<CalibrationScan> scans = calibration_scans(pass, config.preprocess.deskew);
  std::erase_if(scans, [](const CalibrationScan& s) { return s.cloud.empty(); });
  scans_used = static_cast<int>(scans.size());
  level_with_walls(scans);
  ElevationCalibration c = ElevationCalibration::estimate(scans);
  c.drop_below(config.calibration.min_offset_deg * M_PI / 180.0);
  return c.num_offsets() > 0 ? std::make_shared<const ElevationCalibration>(std::move(c)) : nullptr;
}

}  // namespace

SelfCalibration self_calibrate_elevation(const std::function<std::unique_ptr<ScanSource>()>& open, const MappingConfig& config,
                                         const PipelineOptions& options, const std::function<void(int)>& on_frame,
                                         const std::atomic<bool>* stop) {
  if (options.elevation_calibration) throw Error("self_calibrate_elevation: the scans are calibrated already");
  SelfCalibration r;
  const auto [with_rings, checked] = scans_with_rings(*open());
  if (2 * with_rings <= checked || checked == 0) {
    r.summary = format("not estimated: %d of the first %d scans show rings of fixed elevation, as a spinning multi-beam "
                       "sensor's would",
                       with_rings, checked);
    return r;
  }
  PipelineOptions pass_options = options;
  for (int p = 0; p < config.calibration.passes && !(stop && stop->load()); ++p) {
    OdometryPass pass = run_odometry(*open(), config, pass_options, on_frame, p * r.frames, stop);
    if (stop && stop->load()) return r;  // the run ends: nothing is mapped
    if (p == 0) {
      r.frames = static_cast<int>(pass.poses.size());
      r.travelled = travelled(pass.poses);
      r.odometry = pass.poses;
      if (r.travelled < config.calibration.min_travel) {
        r.summary = format("not estimated: the first %d frames travel %.1f m, less than calibration.min_travel (%.0f m)",
                           r.frames, r.travelled, config.calibration.min_travel);
        return r;
      }
    }
    pass_options.elevation_calibration = estimate(pass, config, r.scans);
    r.passes = p + 1;
    if (!pass_options.elevation_calibration) break;
  }
  if (!pass_options.elevation_calibration) {
    if (r.passes > 0)
      r.summary = format("none needed: no offset of %.2f deg or more found from the odometry of the first %d frames (%.0f m, "
                         "%d scans)",
                         config.calibration.min_offset_deg, r.frames, r.travelled, r.scans);
    return r;
  }
  r.calibration = pass_options.elevation_calibration;
  r.bins = r.calibration->num_offsets();
  r.largest_deg = r.calibration->largest_offset() * 180.0 / M_PI;
  r.summary = format("estimated from the odometry of the first %d frames (%.0f m, %d scans, %d passes): offsets for %d "
                     "elevations, largest %.3f deg",
                     r.frames, r.travelled, r.scans, r.passes, r.bins, r.largest_deg);
  return r;
}

}  // namespace gcmap
