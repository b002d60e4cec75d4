#include "gcmap/viz/plots.hpp"

#include <cstdio>
#include <filesystem>

#include "gcmap/core/error.hpp"
#include "gcmap/eval/trajectory_metrics.hpp"
#include "gcmap/io/trajectory_io.hpp"
#include "gcmap/viz/chart.hpp"
#include "gcmap/viz/run_data.hpp"

namespace gcmap::viz {

namespace {

namespace fs = std::filesystem;
constexpr int kWidth = 1000;

std::string fmt(const char* f, double v) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), f, v);
  return buf;
}

WrittenFile fig10(const RunStats& stats, const std::string& path, FigureFormat format) {
  LineChart time{
      "Global optimization per new submap (Fig. 10)", "submaps in the graph", "optimization time [ms]", {}, false, true};
  LineChart factors{"Global factors", "submaps in the graph", "factors", {}, false, true};
  Series t{"time", {}, {}, chart_colours::estimate, true}, f{"factors", {}, {}, chart_colours::odometry, true};
  for (const InsertionStats& p : stats.per_submap) {
    t.x.push_back(p.submaps);
    t.y.push_back(p.global_optimization_ms);
    f.x.push_back(p.submaps);
    f.y.push_back(p.factors);
  }
  time.series.push_back(t);
  factors.series.push_back(f);
  Canvas c(kWidth, 900, format);
  if (stats.per_submap.empty()) {
    draw_message(c, time.title, "stats.json has no per-submap entries", {0, 0, kWidth, 900});
  } else {
    draw_line_chart(c, time, {0, 0, kWidth, 450});
    draw_line_chart(c, factors, {0, 450, kWidth, 450});
  }
  write_figure(path, c);
  return {path,
          "global optimization time and factors against submaps (" + std::to_string(stats.per_submap.size()) + " insertions)"};
}

WrittenFile timings(const RunStats& stats, const std::string& path, FigureFormat format) {
  BarChart chart{
      "Processing time per call of each module (Table III)", "mean time per call [ms] (whisker: one standard deviation)", {}};
  for (const ModuleTiming& m : stats.timing) {
    if (!m.count) continue;
    std::string name = m.module;
    for (char& ch : name) ch = ch == '_' ? ' ' : ch;
    chart.bars.push_back(
        {name, m.mean_ms, m.std_ms,
         fmt("%.1f", m.mean_ms) + " +- " + fmt("%.1f", m.std_ms) + " ms, " + std::to_string(m.count) + " calls"});
  }
  const int h = 140 + 45 * static_cast<int>(std::max<size_t>(chart.bars.size(), 2));
  Canvas c(kWidth, h, format);
  if (chart.bars.empty()) draw_message(c, chart.title, "no module ran", {0, 0, kWidth, static_cast<double>(h)});
  else draw_bar_chart(c, chart, {0, 0, kWidth, static_cast<double>(h)});
  write_figure(path, c);
  return {path, "per-module timings (" + std::to_string(chart.bars.size()) + " modules)"};
}

// Top-down: the two axes along which the ground truth spreads most (KITTI's camera frame is y-down).
std::pair<int, int> ground_plane(const Poses& gt) {
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e300), hi = -lo;
  for (const auto& T : gt) lo = lo.cwiseMin(T.translation()), hi = hi.cwiseMax(T.translation());
  Eigen::Index up;
  (hi - lo).minCoeff(&up);
  return {up == 0 ? 1 : 0, up == 2 ? 1 : 2};
}

Series positions(const std::string& label, const Poses& poses, const Eigen::Isometry3d& T_gt_est, std::pair<int, int> axes,
                 Rgb colour) {
  Series s{label, {}, {}, colour, false};
  for (const auto& T : poses) {
    const Eigen::Vector3d p = T_gt_est * T.translation();
    s.x.push_back(p[axes.first]);
    s.y.push_back(p[axes.second]);
  }
  return s;
}

WrittenFile trajectories(const Poses& gt, const Poses& est, const Poses* odom, const std::string& path, FigureFormat format) {
  static const char* names[] = {"x [m]", "y [m]", "z [m]"};
  const auto axes = ground_plane(gt);
  LineChart chart{"Trajectory, top-down (estimates aligned to the ground truth, SE(3))",
                  names[axes.first],
                  names[axes.second],
                  {},
                  true,
                  false};
  chart.series.push_back(positions("ground truth", gt, Eigen::Isometry3d::Identity(), axes, chart_colours::ground_truth));
  chart.series.back().width = 6.0;  // under the estimates, which often cover it
  if (odom) {
    const AbsoluteError a = absolute_trajectory_error(gt, *odom);
    chart.series.push_back(
        positions("odometry (ATE " + fmt("%.3f", a.rmse) + " m)", *odom, a.T_gt_est, axes, chart_colours::odometry));
  }
  const AbsoluteError a = absolute_trajectory_error(gt, est);
  chart.series.push_back(
      positions("global optimization (ATE " + fmt("%.3f", a.rmse) + " m)", est, a.T_gt_est, axes, chart_colours::estimate));
  Canvas c(kWidth, kWidth, format);
  draw_line_chart(c, chart, {0, 0, kWidth, kWidth});
  write_figure(path, c);
  return {path, "estimated" + std::string(odom ? ", odometry" : "") + " and ground-truth trajectories from above"};
}

Series per_length(const std::string& label, const KittiError& k, bool rotation, Rgb colour) {
  Series s{label, {}, {}, colour, true};
  for (const KittiSegmentError& e : k.per_length) {
    if (!e.count) continue;
    s.x.push_back(e.length);
    s.y.push_back(rotation ? e.rotation_deg_per_100m : e.translation_percent);
  }
  return s;
}

WrittenFile kitti_errors(const Poses& gt, const Poses& est, const Poses* odom, const std::string& path, FigureFormat format) {
  const KittiError ke = kitti_relative_error(gt, est);
  LineChart t{"KITTI relative error: translation", "segment length [m]", "translation error [%]", {}, false, true};
  LineChart r{"KITTI relative error: rotation", "segment length [m]", "rotation error [deg/100 m]", {}, false, true};
  t.x_min = r.x_min = 50.0;  // the devkit's lengths, 100 .. 800 m
  t.x_max = r.x_max = 850.0;
  if (odom) {
    const KittiError ko = kitti_relative_error(gt, *odom);
    t.series.push_back(
        per_length("odometry (mean " + fmt("%.3f", ko.translation_percent) + " %)", ko, false, chart_colours::odometry));
    r.series.push_back(
        per_length("odometry (mean " + fmt("%.4f", ko.rotation_deg_per_100m) + ")", ko, true, chart_colours::odometry));
  }
  t.series.push_back(
      per_length("global optimization (mean " + fmt("%.3f", ke.translation_percent) + " %)", ke, false, chart_colours::estimate));
  r.series.push_back(
      per_length("global optimization (mean " + fmt("%.4f", ke.rotation_deg_per_100m) + ")", ke, true, chart_colours::estimate));
  Canvas c(kWidth, 900, format);
  if (!ke.num_segments) {
    draw_message(c, t.title, "trajectory shorter than 100 m: no KITTI segments", {0, 0, kWidth, 900});
  } else {
    draw_line_chart(c, t, {0, 0, kWidth, 450});
    draw_line_chart(c, r, {0, 450, kWidth, 450});
  }
  write_figure(path, c);
  return {path, "KITTI translational and rotational error per segment length (" + std::to_string(ke.num_segments) + " segments)"};
}

Poses load_estimate(const std::string& path, const PlotOptions& o, size_t expected) {
  Poses p = read_trajectory(path).poses;
  if (p.size() != expected)
    throw Error(path + ": has " + std::to_string(p.size()) + " poses, " + o.ground_truth + " has " + std::to_string(expected));
  if (!o.calib.empty()) {
    const Eigen::Isometry3d Tr = read_kitti_calib_tr(o.calib);
    for (auto& T : p) T = Tr * T * Tr.inverse();
  }
  return p;
}

}  // namespace

std::vector<WrittenFile> write_plots(const std::string& run_dir, const std::string& out_dir, const PlotOptions& o) {
  const RunStats stats = read_stats_json(run_file(run_dir, "stats.json"));
  std::error_code ec;
  fs::create_directories(out_dir, ec);
  if (!fs::is_directory(out_dir, ec)) throw Error(out_dir + ": cannot create the folder");
  auto out = [&](const char* name) { return (fs::path(out_dir) / (name + std::string(figure_extension(o.format)))).string(); };
  std::vector<WrittenFile> written{fig10(stats, out("global_optimization"), o.format), timings(stats, out("timings"), o.format)};
  if (o.ground_truth.empty()) return written;
  const Poses gt = read_trajectory(o.ground_truth).poses;
  const Poses est = load_estimate(run_file(run_dir, "trajectory.kitti"), o, gt.size());
  const std::string odom_path = run_file(run_dir, "odometry.kitti");
  const bool with_odom = fs::exists(odom_path, ec);
  const Poses odom = with_odom ? load_estimate(odom_path, o, gt.size()) : Poses{};
  written.push_back(trajectories(gt, est, with_odom ? &odom : nullptr, out("trajectory"), o.format));
  written.push_back(kitti_errors(gt, est, with_odom ? &odom : nullptr, out("kitti_errors"), o.format));
  return written;
}

}  // namespace gcmap::viz
