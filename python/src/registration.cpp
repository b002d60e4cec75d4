// Pairwise registration as `gcmap register` does it: downsampling, covariances, then VGICP against
// the target's voxel map (on the CPU, or through the GPU backend as a two-pose graph) or GICP.
#include <pybind11/stl.h>
#include <tbb/global_control.h>

#include "arrays.hpp"
#include "bindings.hpp"
#include "gcmap/core/preprocess.hpp"
#include "gcmap/cuda/cuda_backend.hpp"
#include "gcmap/graph/matching_graph.hpp"
#include "gcmap/registration/registration.hpp"

namespace gcmap::python {

namespace {

enum class Method { vgicp, gicp };

struct PairOptions {
  double voxel = 1.0, downsample = 0.25;
  Method method = Method::vgicp;
  int max_iterations = 64, threads = 0;
  Device device = Device::automatic;
};

struct PairResult {
  RegistrationResult r;
  double overlap = 0.0;
};

PointCloud prepared(const PointCloud& cloud, const PairOptions& o) {
  PointCloud out = o.downsample > 0 ? voxel_downsample(cloud, o.downsample) : cloud;
  estimate_covariances(out);
  return out;
}

PairResult register_pair(const PointCloud& target_in, const PointCloud& source_in, const Eigen::Isometry3d& init,
                         const PairOptions& o) {
  std::unique_ptr<tbb::global_control> threads;
  if (o.threads > 0) threads = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, o.threads);
  // GICP has no GPU path; VGICP goes to the GPU when asked (or, for auto, when one answers).
  const bool gpu = o.method == Method::vgicp && o.device != Device::cpu && (o.device == Device::cuda || cuda::device_available());
  const std::shared_ptr<LinearizationBackend> backend = gpu ? cuda::make_backend(Device::cuda) : nullptr;
  const PointCloud target = prepared(target_in, o);
  PointCloud source = prepared(source_in, o);
  auto voxels = std::make_shared<GaussianVoxelMap>(o.voxel);
  voxels->insert(target);
  voxels->finalize();
  RegistrationConfig config;
  config.max_iterations = o.max_iterations;
  PairResult out;
  if (o.method == Method::gicp) {
    const GicpTarget gicp_target(std::make_shared<const PointCloud>(target));
    out.r = align_gicp(source, gicp_target, init, config);
  } else if (backend) {
    out.r = backend->align(source, voxels, init, config);
  } else {
    out.r = align_vgicp(source, *voxels, init, config);
  }
  out.overlap = overlap(source, *voxels, out.r.T_target_source);
  return out;
}

PairOptions pair_options(double voxel, double downsample, const std::string& method, int max_iterations, int threads,
                         const std::string& device) {
  PairOptions o;
  if (!(voxel > 0)) throw Error("voxel: must be positive");
  if (!(downsample >= 0)) throw Error("downsample: must be >= 0");
  if (max_iterations < 1) throw Error("max_iterations: must be >= 1");
  if (threads < 0) throw Error("threads: must be >= 0");
  if (method != "vgicp" && method != "gicp") throw Error("method: must be vgicp or gicp, got '" + method + "'");
  o.voxel = voxel;
  o.downsample = downsample;
  o.method = method == "gicp" ? Method::gicp : Method::vgicp;
  o.max_iterations = max_iterations;
  o.threads = threads;
  o.device = parse_device(device, "device");
  return o;
}

}  // namespace

void bind_registration(py::module_& m) {
  py::class_<PairResult>(m, "RegistrationResult", "The outcome of gcmap.register().")
      .def_property_readonly(
          "T_target_source", [](const PairResult& p) { return pose_array(p.r.T_target_source); },
          "4x4 float64: maps source points into the target frame.")
      .def_property_readonly(
          "converged", [](const PairResult& p) { return p.r.converged; },
          "True when the last accepted step was below 1e-4 rad and 1e-4 m.")
      .def_property_readonly("iterations", [](const PairResult& p) { return p.r.iterations; })
      .def_property_readonly(
          "error", [](const PairResult& p) { return p.r.error; }, "Sum of the per-point matching costs at the solution.")
      .def_property_readonly(
          "num_inliers", [](const PairResult& p) { return p.r.num_inliers; },
          "Source points (after downsampling) with a target voxel or neighbour.")
      .def_property_readonly(
          "overlap", [](const PairResult& p) { return p.overlap; },
          "Fraction of source points that fall in an occupied target voxel.")
      .def("__repr__", [](const PairResult& p) {
        const Eigen::Vector3d t = p.r.T_target_source.translation();
        return "RegistrationResult(converged=" + std::string(p.r.converged ? "True" : "False") +
               ", iterations=" + std::to_string(p.r.iterations) + ", translation=[" + std::to_string(t.x()) + ", " +
               std::to_string(t.y()) + ", " + std::to_string(t.z()) + "], overlap=" + std::to_string(p.overlap) + ")";
      });

  m.def(
      "register",
      [](const py::array& target, const py::array& source, const std::optional<py::array>& init, double voxel, double downsample,
         const std::string& method, int max_iterations, int threads, const std::string& device) {
        const PairOptions o = pair_options(voxel, downsample, method, max_iterations, threads, device);
        const PointCloud t = to_cloud(target, "target"), s = to_cloud(source, "source");
        if (t.size() < 10) throw Error("target: too few finite points (" + std::to_string(t.size()) + ")");
        if (s.size() < 10) throw Error("source: too few finite points (" + std::to_string(s.size()) + ")");
        const Eigen::Isometry3d T_init = init ? to_pose(*init, "init") : Eigen::Isometry3d::Identity();
        py::gil_scoped_release release;
        return register_pair(t, s, T_init, o);
      },
      py::arg("target"), py::arg("source"), py::arg("init") = py::none(), py::kw_only(), py::arg("voxel") = 1.0,
      py::arg("downsample") = 0.25, py::arg("method") = "vgicp", py::arg("max_iterations") = 64, py::arg("threads") = 0,
      py::arg("device") = "auto",
      R"(Aligns source to target and returns a RegistrationResult (T_target_source, converged, ...).

target, source: (N, 3) or (N, 4) float32/float64 arrays in their own frames.
init: initial 4x4 T_target_source (default identity).
voxel: VGICP voxel size in m; downsample: voxel downsampling of both clouds in m (0: off).
method: "vgicp" (voxelized GICP, the paper's cost) or "gicp" (nearest neighbour, CPU only).
threads: worker threads (0: all cores). device: "cpu", "cuda" or "auto" (a GPU when one answers).
The GIL is released while it runs. Raises ValueError for bad arrays or options.)");
}

}  // namespace gcmap::python
