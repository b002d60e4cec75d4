#pragma once
// NumPy <-> gcmap conversions and the exceptions the bindings raise. Inputs are read in place
// through their strides (float32 or float64, C or Fortran order); outputs hand their C++ storage
// to NumPy without a copy.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <filesystem>
#include <memory>
#include <optional>
#include <vector>

#include "gcmap/core/error.hpp"
#include "gcmap/core/point_cloud.hpp"

namespace gcmap::python {

namespace py = pybind11;

// Raised as FileNotFoundError and RuntimeError (every other gcmap::Error becomes ValueError).
struct FileMissing : Error {
  using Error::Error;
};
struct StateError : Error {
  using Error::Error;
};

// Calls f(); an Error about `path` while the file does not exist becomes FileMissing.
template <typename F>
auto with_file(const std::string& path, F&& f) {
  try {
    return f();
  } catch (const Error& e) {
    std::error_code ec;
    if (!std::filesystem::exists(path, ec)) throw FileMissing(e.what());
    throw;
  }
}

// An (N,3) or (N,4) float32/float64 array (the 4th column is intensity). `times` (per-point
// seconds) and `intensities`, when given, are (N,). Rows with a non-finite coordinate are dropped,
// as the file readers do. Throws Error naming the argument for another shape or dtype.
PointCloud to_cloud(py::handle array, const char* what, py::handle times = py::none(), py::handle intensities = py::none());
// A 4x4 rigid transform (float, finite, rotation orthonormal within 1e-3).
Eigen::Isometry3d to_pose(py::handle array, const char* what);
// (n,4,4).
std::vector<Eigen::Isometry3d> to_poses(py::handle array, const char* what);
// An optional array argument as a handle (None when absent).
inline py::handle or_none(const std::optional<py::array>& a) { return a ? py::handle(*a) : py::handle(Py_None); }

// (N,3) float32 owning the cloud's points; `intensities` (N,) float32 likewise when wanted.
py::array points_array(PointCloud&& cloud, py::object* intensities = nullptr);
// Read-only (N,3) float32 view of a shared cloud, which it keeps alive.
py::array points_view(std::shared_ptr<const PointCloud> cloud);
py::array pose_array(const Eigen::Isometry3d& T);
py::array poses_array(const std::vector<Eigen::Isometry3d>& poses);

}  // namespace gcmap::python
