// The simulator and the evaluation metrics.
#include "arrays.hpp"
#include "bindings.hpp"
#include "gcmap/eval/map_entropy.hpp"
#include "gcmap/eval/trajectory_metrics.hpp"
#include "gcmap/sim/simulator.hpp"

namespace gcmap::python {

namespace {

// Ground truth relative to frame 0, as the pipeline's trajectory (and poses.txt of `gcmap simulate`).
std::vector<Eigen::Isometry3d> relative_poses(const sim::Simulator& s) {
  std::vector<Eigen::Isometry3d> out;
  for (const auto& T : s.poses()) out.push_back(s.poses().front().inverse() * T);
  return out;
}

std::pair<Poses, Poses> trajectories(py::handle gt, py::handle est) {
  Poses g = to_poses(gt, "gt"), e = to_poses(est, "est");
  if (g.size() != e.size())
    throw Error("gt and est differ in length: " + std::to_string(g.size()) + " vs " + std::to_string(e.size()) + " poses");
  if (g.size() < 2) throw Error("gt: need at least 2 poses");
  return {std::move(g), std::move(e)};
}

void bind_simulator(py::module_& m) {
  py::class_<sim::Simulator>(m, "Simulation", R"(A simulated drive through a street grid (what `gcmap simulate` writes).

A sequence of frames: sim[i] and iteration give (points, gt_pose) with points the (N, 3) float32
scan in the sensor frame and gt_pose the true 4x4 pose relative to frame 0. Scans are generated on
access (deterministic for seed and frame), with the GIL released.)")
      .def("__len__", &sim::Simulator::num_frames)
      .def("__getitem__",
           [](const sim::Simulator& s, long i) {
             if (i < 0) i += static_cast<long>(s.num_frames());
             if (i < 0 || i >= static_cast<long>(s.num_frames())) throw py::index_error("frame out of range");
             PointCloud scan;
             {
               py::gil_scoped_release release;
               scan = s.scan(static_cast<size_t>(i));
             }
             return py::make_tuple(points_array(std::move(scan)), pose_array(s.poses().front().inverse() * s.poses()[i]));
           })
      .def_property_readonly(
          "poses", [](const sim::Simulator& s) { return poses_array(relative_poses(s)); },
          "(n, 4, 4) float64: the true pose of every frame relative to frame 0.")
      .def_property_readonly("path_length", &sim::Simulator::path_length, "Length of the drive in m.")
      .def_property_readonly("description", [](const sim::Simulator& s) { return s.scenario().description; });

  m.def(
      "simulate",
      [](const std::string& scenario, uint64_t seed, int frames, const std::string& sensor, double noise) {
        sim::SimulationConfig c;
        c.scenario = scenario;
        c.seed = seed;
        c.frames = frames;
        c.sensor = sensor;
        c.noise = noise;
        if (frames < 0) throw Error("frames: must be >= 0");
        py::gil_scoped_release release;
        return std::make_unique<sim::Simulator>(c);
      },
      py::arg("scenario") = "small", py::arg("seed") = 1, py::kw_only(), py::arg("frames") = 0, py::arg("sensor") = "",
      py::arg("noise") = 0.02,
      R"(A Simulation: iterate it for (points, gt_pose) frames.

scenario: "small" (one 160 m block, 150 frames), "loop" (1.55 km, 1500 frames) or "corridor"
(500 m of flat facades). frames: how many frames along the whole drive (0: the scenario's).
sensor: "hdl64", "vlp16", "os1-64", "os1-128", "avia" or "mid360" (empty: the scenario's, hdl64 but for
"handheld"). noise: range noise sigma in m.)");
}

}  // namespace

void bind_sim_eval(py::module_& m) {
  bind_simulator(m);
  py::module_ eval = m.def_submodule("eval", "Trajectory and map metrics.");
  eval.def(
      "kitti",
      [](const py::array& gt, const py::array& est) {
        const auto [g, e] = trajectories(gt, est);
        const KittiError k = kitti_relative_error(g, e);
        py::list per_length;
        for (const KittiSegmentError& s : k.per_length)
          per_length.append(py::dict(py::arg("length") = s.length, py::arg("translation_percent") = s.translation_percent,
                                     py::arg("rotation_deg_per_100m") = s.rotation_deg_per_100m, py::arg("count") = s.count));
        return py::dict(py::arg("translation_percent") = k.translation_percent,
                        py::arg("rotation_deg_per_100m") = k.rotation_deg_per_100m, py::arg("num_segments") = k.num_segments,
                        py::arg("per_length") = per_length);
      },
      py::arg("gt"), py::arg("est"),
      R"(KITTI odometry relative error over 100..800 m segments of (n, 4, 4) trajectories: a dict with
translation_percent, rotation_deg_per_100m, num_segments and per_length. A drive shorter than 100 m
has no segment (num_segments 0).)");
  eval.def(
      "ate",
      [](const py::array& gt, const py::array& est) {
        const auto [g, e] = trajectories(gt, est);
        const AbsoluteError a = absolute_trajectory_error(g, e);
        return py::dict(py::arg("rmse") = a.rmse, py::arg("mean") = a.mean, py::arg("max") = a.max,
                        py::arg("T_gt_est") = pose_array(a.T_gt_est));
      },
      py::arg("gt"), py::arg("est"),
      "Absolute trajectory error in m after SE(3) alignment of est onto gt: a dict with rmse, mean, max, T_gt_est.");
  eval.def(
      "rpe",
      [](const py::array& gt, const py::array& est) {
        const auto [g, e] = trajectories(gt, est);
        const RelativePoseError r = relative_pose_error(g, e);
        return py::dict(py::arg("translation_rmse") = r.translation_rmse, py::arg("translation_mean") = r.translation_mean,
                        py::arg("translation_max") = r.translation_max, py::arg("rotation_rmse_deg") = r.rotation_rmse_deg,
                        py::arg("rotation_mean_deg") = r.rotation_mean_deg, py::arg("rotation_max_deg") = r.rotation_max_deg);
      },
      py::arg("gt"), py::arg("est"), "Frame-to-frame relative pose error (m, deg): a dict of rmse, mean and max.");
  eval.def(
      "mme",
      [](const py::array& points, double radius, int min_neighbors) {
        if (!(radius > 0)) throw Error("radius: must be positive");
        if (min_neighbors < 4) throw Error("min_neighbors: must be at least 4");
        const PointCloud map = to_cloud(points, "points");
        MapEntropy e;
        {
          py::gil_scoped_release release;
          e = mean_map_entropy(map, radius, min_neighbors);
        }
        return py::dict(py::arg("mean") = e.mean, py::arg("stddev") = e.stddev, py::arg("num_points") = e.num_points,
                        py::arg("num_skipped") = e.num_skipped);
      },
      py::arg("points"), py::arg("radius") = 0.3, py::arg("min_neighbors") = 15,
      R"(Mean map entropy (Razlaw et al. 2015) of an (N, 3) map: lower is crisper. A dict with mean,
stddev, num_points (that contributed) and num_skipped (too few neighbours within radius).)");
}

}  // namespace gcmap::python
