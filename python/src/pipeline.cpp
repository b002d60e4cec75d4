// MappingPipeline scan by scan. Calls release the GIL and take the pipeline's own lock, so other
// Python threads run while it maps and two threads never enter the same pipeline at once.
#include <pybind11/stl.h>

#include <mutex>

#include "arrays.hpp"
#include "bindings.hpp"
#include "gcmap/cuda/cuda_backend.hpp"
#include "gcmap/mapping/pipeline.hpp"
#include "gcmap/mapping/report.hpp"

namespace gcmap::python {

namespace {

using DoubleArray = py::array_t<double, py::array::c_style | py::array::forcecast>;

py::object from_json(const Json& json) { return py::module_::import("json").attr("loads")(json.dump()); }

class Pipeline {
 public:
  Pipeline(const MappingConfig& config, const std::string& device, bool kitti_hdl64) {
    const Device d = parse_device(device, "device");
    py::gil_scoped_release release;
    PipelineOptions options;
    options.kitti_hdl64 = kitti_hdl64;
    pipeline_ = std::make_unique<MappingPipeline>(config, cuda::make_backend(d), options);
  }

  // f(pipeline) without the GIL, under the pipeline's lock.
  template <typename F>
  auto locked(F&& f) {
    py::gil_scoped_release release;
    std::lock_guard lock(mutex_);
    return f(*pipeline_);
  }

  py::tuple add_scan(const py::array& points, double stamp, const std::optional<py::array>& times,
                     const std::optional<py::array>& T_odom) {
    PointCloud cloud = to_cloud(points, "points", or_none(times));
    std::optional<Eigen::Isometry3d> odom;
    if (T_odom) odom = to_pose(*T_odom, "T_odom");
    const Frame frame = locked([&](MappingPipeline& p) {
      if (p.finished()) throw StateError("add_scan: the pipeline is finished (finish() was called)");
      return p.add_scan(std::move(cloud), stamp, odom);
    });
    return py::make_tuple(pose_array(frame.T_world_frame), to_string(frame.status));
  }

  // One sample (a float stamp, gyro and accel of shape (3,)) or many ((n,), (n,3), (n,3)).
  void add_imu(const DoubleArray& stamps, const DoubleArray& gyro,
               const DoubleArray& accel) {
    const bool one = stamps.ndim() == 0;
    const py::ssize_t n = one ? 1 : stamps.shape(0);
    const auto check = [&](const DoubleArray& a, const char* what) {
      const bool ok = one ? a.ndim() == 1 && a.shape(0) == 3 : a.ndim() == 2 && a.shape(0) == n && a.shape(1) == 3;
      if (!ok) throw Error(std::string(what) + ": expected shape " + (one ? "(3,)" : "(n, 3) with n the number of stamps"));
    };
    if (!one && stamps.ndim() != 1) throw Error("stamps: expected a float or an (n,) array");
    check(gyro, "gyro"), check(accel, "accel");
    std::vector<ImuSample> samples(static_cast<size_t>(n));
    const double *t = stamps.data(), *g = gyro.data(), *a = accel.data();
    for (py::ssize_t i = 0; i < n; ++i)
      samples[i] = {t[i], Eigen::Vector3d(g[3 * i], g[3 * i + 1], g[3 * i + 2]), Eigen::Vector3d(a[3 * i], a[3 * i + 1], a[3 * i + 2])};
    locked([&](MappingPipeline& p) {
      if (p.finished()) throw StateError("add_imu: the pipeline is finished (finish() was called)");
      for (const ImuSample& s : samples) p.add_imu(s);
    });
  }

  void finish(std::optional<int> max_iterations) {
    if (max_iterations && *max_iterations < 0) throw Error("max_iterations: must be >= 0");
    locked([&](MappingPipeline& p) {
      if (p.finished()) throw StateError("finish: already called");
      p.finish(max_iterations);
    });
  }

  py::list submaps() {
    std::vector<Eigen::Isometry3d> poses;
    const std::vector<Submap> submaps = locked([&](MappingPipeline& p) {
      const Eigen::Isometry3d T_out_world = p.mapper().output_from_world();
      for (const Submap& s : p.submaps()) poses.push_back(T_out_world * p.mapper().submap_pose(s.id));
      return p.submaps();
    });
    py::list out;
    for (size_t k = 0; k < submaps.size(); ++k) {
      py::dict d;
      d["id"] = submaps[k].id;
      d["pose"] = pose_array(poses[k]);
      d["keyframes"] = submaps[k].keyframes;
      d["points"] = points_view(submaps[k].cloud);
      out.append(d);
    }
    return out;
  }

  py::list statuses() {
    const auto statuses = locked([](MappingPipeline& p) { return p.statuses(); });
    py::list out;
    for (FrameStatus s : statuses) out.append(to_string(s));
    return out;
  }

 private:
  std::mutex mutex_;
  std::unique_ptr<MappingPipeline> pipeline_;
};

}  // namespace

void bind_pipeline(py::module_& m) {
  using P = Pipeline;
  using MP = MappingPipeline;
  py::class_<P>(m, "MappingPipeline", R"(The whole mapping system, scan by scan (the library behind `gcmap map`).

    pipeline = gcmap.MappingPipeline(gcmap.MappingConfig(), device="auto")
    for stamp, points in scans:
        pose, status = pipeline.add_scan(points, stamp)
    pipeline.finish()
    poses = pipeline.trajectory        # (n, 4, 4), frame 0 the identity

Scans go in in their sensor frame with non-decreasing stamps. Every call releases the GIL.)")
      .def(py::init<const MappingConfig&, const std::string&, bool>(), py::arg("config") = MappingConfig(),
           py::arg("device") = "auto", py::arg("kitti_hdl64") = false,
           R"(config: a MappingConfig (validated: ValueError naming a bad key).
device: where factors are linearized: "cpu", "cuda" or "auto" (a GPU when one answers).
kitti_hdl64: the scans are KITTI's own HDL-64 recordings (applies the 0.22 deg elevation correction
when config.preprocess.kitti_vertical_correction is on).)")
      .def("add_scan", &P::add_scan, py::arg("points"), py::arg("stamp"), py::arg("times") = py::none(),
           py::arg("T_odom") = py::none(),
           R"(Maps one scan; returns (pose, status).

points: (N, 3) or (N, 4) float32/float64 in the sensor frame (rows with NaN are dropped).
stamp: seconds, not before the previous scan's. times: optional (N,) per-point seconds relative to
stamp, for motion compensation. T_odom: optional 4x4 odometry pose used instead of scan matching.
pose: the current 4x4 estimate of this frame (later frames and finish() still move it).
status: "keyframe", "skipped" (overlaps the last keyframe) or "unusable" (empty or too few points:
placed by the motion model). RuntimeError after finish().)")
      .def("add_imu", &P::add_imu, py::arg("stamp"), py::arg("gyro"), py::arg("accel"),
           R"(IMU samples, before the scans they span: stamp a float and gyro, accel (3,), or stamps (n,)
and gyro, accel (n, 3). Gyro in rad/s, acceleration in m/s^2, both in the IMU frame (config.imu places it
on the LiDAR), stamps on the IMU's clock (config.imu.time_offset), increasing. The gyro deskews the sweeps
they span, the LiDAR-inertial state predicts them (config.imu.inertial_odometry), the accelerometer levels the map (config.imu.level_map: z up, the poses then in that frame);
ignored when config.imu.use is off. ValueError for a bad shape or a stamp not increasing.)")
      .def("finish", &P::finish, py::arg("max_iterations") = py::none(),
           "Closes the open submap and runs the final global optimization (at most max_iterations; 0 skips it).")
      .def_property_readonly("finished", [](P& p) { return p.locked([](MP& mp) { return mp.finished(); }); })
      .def("__len__", [](P& p) { return p.locked([](MP& mp) { return mp.num_frames(); }); })
      .def_property_readonly(
          "trajectory", [](P& p) { return poses_array(p.locked([](MP& mp) { return mp.trajectory(); })); },
          "(n, 4, 4) float64: the current estimate of every frame, frame 0 the identity.")
      .def_property_readonly(
          "odometry", [](P& p) { return poses_array(p.locked([](MP& mp) { return mp.odometry(); })); },
          "(n, 4, 4) float64: the odometry pose of every frame (or the T_odom given).")
      .def_property_readonly(
          "stamps", [](P& p) { return py::array(py::cast(p.locked([](MP& mp) { return mp.stamps(); }))); },
          "(n,) float64: the stamp of every frame.")
      .def_property_readonly("statuses", &P::statuses, "The status of every frame: keyframe, skipped or unusable.")
      .def_property_readonly("submaps", &P::submaps,
                             "A list of dicts: id, pose (4x4, output frame), keyframes (frame indices), points "
                             "((N, 3) float32, read-only, in the submap frame).")
      .def_property_readonly(
          "graph", [](P& p) { return from_json(p.locked([](MP& mp) { return graph_json(mp); })); },
          "graph.json of `gcmap map` as a dict: submaps, factors (with final errors), loop_candidates.")
      .def_property_readonly(
          "factors", [](P& p) { return py::object(from_json(p.locked([](MP& mp) { return graph_json(mp); }))["factors"]); },
          "The global factors as dicts: type (matching_cost, odometry, se3, loop), source, target, overlap, final_error.")
      .def_property_readonly(
          "loops", [](P& p) { return py::object(from_json(p.locked([](MP& mp) { return graph_json(mp); }))["loop_candidates"]); },
          "Every verified loop candidate as a dict: source, target, descriptor_distance, inlier_fraction, inlier_rmse, "
          "conditioning, accepted.")
      .def_property_readonly(
          "stats", [](P& p) { return from_json(p.locked([](MP& mp) { return stats_json(mp); })); },
          "stats.json of `gcmap map` as a dict: frames, rate, device, per-module timings, optimization per submap.")
      .def_property_readonly(
          "device", [](P& p) { return p.locked([](MP& mp) { return mp.backend().name(); }); },
          "\"cpu\" or \"cuda: <device name>\".")
      .def_property_readonly(
          "config", [](P& p) { return p.locked([](MP& mp) { return mp.config(); }); }, "A copy of the config in use.")
      .def(
          "map",
          [](P& p, std::optional<double> resolution) {
            if (resolution && !(*resolution > 0)) throw Error("resolution: must be positive");
            return points_array(p.locked([&](MP& mp) { return mp.map(resolution.value_or(mp.config().output.map_resolution)); }));
          },
          py::arg("resolution") = py::none(),
          "Every submap in the output frame, voxel-downsampled (default: config.output.map_resolution), as (N, 3) float32.");
}

}  // namespace gcmap::python
