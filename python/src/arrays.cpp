#include "arrays.hpp"

#include <filesystem>
#include <string>

#include "gcmap/core/preprocess.hpp"

namespace gcmap::python {

namespace {

// NumPy's view of any array-like, without converting its dtype.
py::array as_array(py::handle object, const char* what) {
  py::array a = py::array::ensure(object);
  if (!a) throw Error(std::string(what) + ": expected a NumPy array");
  return a;
}

std::string shape_text(const py::array& a) {
  std::string s = "(";
  for (py::ssize_t d = 0; d < a.ndim(); ++d) s += (d ? ", " : "") + std::to_string(a.shape(d));
  return s + (a.ndim() == 1 ? ",)" : ")");
}

void require_float(const py::array& a, const char* what) {
  const char kind = a.dtype().kind();
  if (kind != 'f' || (a.itemsize() != 4 && a.itemsize() != 8))
    throw Error(std::string(what) + ": expected float32 or float64, got dtype " + py::str(a.dtype()).cast<std::string>());
}

// Element (i, j) of a 2-D float array through its byte strides.
template <typename T>
struct Strided2d {
  const char* data;
  py::ssize_t s0, s1;
  double operator()(py::ssize_t i, py::ssize_t j) const { return *reinterpret_cast<const T*>(data + i * s0 + j * s1); }
};

template <typename T>
void copy_rows(const py::array& a, PointCloud& cloud) {
  const Strided2d<T> at{static_cast<const char*>(a.data()), a.strides(0), a.strides(1)};
  const py::ssize_t n = a.shape(0);
  cloud.points.resize(n);
  for (py::ssize_t i = 0; i < n; ++i) cloud.points[i] = Eigen::Vector3f(at(i, 0), at(i, 1), at(i, 2));
  if (a.shape(1) == 4) {
    cloud.intensities.resize(n);
    for (py::ssize_t i = 0; i < n; ++i) cloud.intensities[i] = static_cast<float>(at(i, 3));
  }
}

std::vector<float> to_floats(py::handle object, size_t n, const char* what) {
  const py::array a = as_array(object, what);
  require_float(a, what);
  if (a.ndim() != 1 || static_cast<size_t>(a.shape(0)) != n)
    throw Error(std::string(what) + ": expected shape (" + std::to_string(n) + ",), got " + shape_text(a));
  std::vector<float> out(n);
  const char* data = static_cast<const char*>(a.data());
  for (size_t i = 0; i < n; ++i) {
    const char* p = data + i * a.strides(0);
    out[i] = a.itemsize() == 4 ? *reinterpret_cast<const float*>(p) : static_cast<float>(*reinterpret_cast<const double*>(p));
  }
  return out;
}

// Hands the vector's buffer to NumPy (a move keeps the buffer in place).
template <typename T>
py::array owning(std::vector<T>&& values, std::vector<py::ssize_t> shape, std::vector<py::ssize_t> strides) {
  if (values.empty()) return py::array_t<float>(shape);
  const float* data = reinterpret_cast<const float*>(values.data());
  auto* heap = new std::vector<T>(std::move(values));
  py::capsule owner(heap, [](void* p) { delete static_cast<std::vector<T>*>(p); });
  return py::array_t<float>(shape, strides, data, owner);
}

Eigen::Isometry3d pose_at(const char* data, py::ssize_t s0, py::ssize_t s1, py::ssize_t itemsize, const char* what) {
  Eigen::Matrix4d M;
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j) {
      const char* p = data + i * s0 + j * s1;
      M(i, j) = itemsize == 4 ? *reinterpret_cast<const float*>(p) : *reinterpret_cast<const double*>(p);
    }
  if (!M.allFinite()) throw Error(std::string(what) + ": has non-finite entries");
  const Eigen::Matrix3d R = M.topLeftCorner<3, 3>();
  if ((R.transpose() * R - Eigen::Matrix3d::Identity()).norm() > 1e-3 || R.determinant() < 0 ||
      (M.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).norm() > 1e-9)
    throw Error(std::string(what) + ": is not a rigid transform (rotation not orthonormal or last row not 0 0 0 1)");
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::Quaterniond(R).normalized().toRotationMatrix();
  T.translation() = M.topRightCorner<3, 1>();
  return T;
}

}  // namespace

PointCloud to_cloud(py::handle object, const char* what, py::handle times, py::handle intensities) {
  const py::array a = as_array(object, what);
  require_float(a, what);
  if (a.ndim() != 2 || (a.shape(1) != 3 && a.shape(1) != 4))
    throw Error(std::string(what) + ": expected shape (N, 3) or (N, 4), got " + shape_text(a));
  PointCloud cloud;
  if (a.itemsize() == 4) copy_rows<float>(a, cloud);
  else copy_rows<double>(a, cloud);
  if (!times.is_none()) cloud.times = to_floats(times, cloud.size(), "times");
  if (!intensities.is_none()) cloud.intensities = to_floats(intensities, cloud.size(), "intensities");
  remove_non_finite(cloud);
  return cloud;
}

Eigen::Isometry3d to_pose(py::handle object, const char* what) {
  const py::array a = as_array(object, what);
  require_float(a, what);
  if (a.ndim() != 2 || a.shape(0) != 4 || a.shape(1) != 4)
    throw Error(std::string(what) + ": expected a 4x4 matrix, got shape " + shape_text(a));
  return pose_at(static_cast<const char*>(a.data()), a.strides(0), a.strides(1), a.itemsize(), what);
}

std::vector<Eigen::Isometry3d> to_poses(py::handle object, const char* what) {
  const py::array a = as_array(object, what);
  require_float(a, what);
  if (a.ndim() != 3 || a.shape(1) != 4 || a.shape(2) != 4)
    throw Error(std::string(what) + ": expected shape (n, 4, 4), got " + shape_text(a));
  std::vector<Eigen::Isometry3d> poses;
  for (py::ssize_t k = 0; k < a.shape(0); ++k)
    poses.push_back(
        pose_at(static_cast<const char*>(a.data()) + k * a.strides(0), a.strides(1), a.strides(2), a.itemsize(), what));
  return poses;
}

py::array points_array(PointCloud&& cloud, py::object* intensities) {
  static_assert(sizeof(Eigen::Vector3f) == 3 * sizeof(float), "points are packed float triples");
  const auto n = static_cast<py::ssize_t>(cloud.size());
  if (intensities) {
    *intensities = cloud.has_intensities() ? py::object(owning(std::move(cloud.intensities), {n}, {py::ssize_t{sizeof(float)}}))
                                           : py::object(py::none());
  }
  return owning(std::move(cloud.points), {n, 3}, {py::ssize_t{3 * sizeof(float)}, py::ssize_t{sizeof(float)}});
}

py::array points_view(std::shared_ptr<const PointCloud> cloud) {
  const auto n = static_cast<py::ssize_t>(cloud->size());
  if (n == 0) return py::array_t<float>(std::vector<py::ssize_t>{0, 3});
  const float* data = cloud->points.front().data();
  auto* keep = new std::shared_ptr<const PointCloud>(std::move(cloud));
  py::capsule owner(keep, [](void* p) { delete static_cast<std::shared_ptr<const PointCloud>*>(p); });
  py::array view =
      py::array_t<float>({n, py::ssize_t{3}}, {py::ssize_t{3 * sizeof(float)}, py::ssize_t{sizeof(float)}}, data, owner);
  py::detail::array_proxy(view.ptr())->flags &= ~py::detail::npy_api::NPY_ARRAY_WRITEABLE_;
  return view;
}

py::array pose_array(const Eigen::Isometry3d& T) {
  py::array_t<double> out({4, 4});
  auto m = out.mutable_unchecked<2>();
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j) m(i, j) = T.matrix()(i, j);
  return out;
}

py::array poses_array(const std::vector<Eigen::Isometry3d>& poses) {
  py::array_t<double> out({static_cast<py::ssize_t>(poses.size()), py::ssize_t{4}, py::ssize_t{4}});
  auto m = out.mutable_unchecked<3>();
  for (size_t k = 0; k < poses.size(); ++k)
    for (int i = 0; i < 4; ++i)
      for (int j = 0; j < 4; ++j) m(k, i, j) = poses[k].matrix()(i, j);
  return out;
}

}  // namespace gcmap::python
