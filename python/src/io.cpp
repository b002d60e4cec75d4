// Point cloud and trajectory files.
#include <pybind11/stl.h>

#include "arrays.hpp"
#include "bindings.hpp"
#include "gcmap/io/point_cloud_io.hpp"
#include "gcmap/io/trajectory_io.hpp"

namespace gcmap::python {

void bind_io(py::module_& m) {
  m.def(
      "read_points",
      [](const std::string& path, const std::string& bin_fields, bool intensities) -> py::object {
        const BinFields fields = parse_bin_fields(bin_fields);
        PointCloud cloud;
        {
          py::gil_scoped_release release;
          cloud = with_file(path, [&] { return read_point_cloud(path, fields); });
        }
        if (!intensities) return points_array(std::move(cloud));
        py::object values;
        py::array points = points_array(std::move(cloud), &values);
        return py::make_tuple(points, values);
      },
      py::arg("path"), py::arg("bin_fields") = "xyzi", py::arg("intensities") = false,
      R"(Reads a point cloud: .bin (KITTI float32 records), .pcd (ascii, binary, binary_compressed) or .ply.

Returns an (N, 3) float32 array of x y z; with intensities=True, a tuple (points, intensities)
where intensities is (N,) float32, or None when the file has none. bin_fields is the layout of
.bin files: "xyzi" (KITTI) or "xyz". Points with a non-finite coordinate are dropped.
Raises FileNotFoundError for a missing file and ValueError for a malformed one.)");

  m.def(
      "write_points",
      [](const std::string& path, const py::array& points, const std::optional<py::array>& intensities,
         const std::string& bin_fields) {
        const BinFields fields = parse_bin_fields(bin_fields);
        const PointCloud cloud = to_cloud(points, "points", py::none(), or_none(intensities));
        py::gil_scoped_release release;
        write_point_cloud(path, cloud, fields);
      },
      py::arg("path"), py::arg("points"), py::arg("intensities") = py::none(), py::arg("bin_fields") = "xyzi",
      R"(Writes a point cloud by extension: binary .ply, binary .pcd or .bin (bin_fields "xyzi": KITTI
records with intensity 0 where none is given, or "xyz").

points is (N, 3) or (N, 4) float32/float64 (the 4th column is intensity); intensities, when
given, is (N,). Rows with a non-finite coordinate are not written. The file is written under a
temporary name and renamed, so a reader never sees half of it.)");

  m.def(
      "read_trajectory",
      [](const std::string& path) {
        const Trajectory t = with_file(path, [&] { return read_trajectory(path); });
        return poses_array(t.poses);
      },
      py::arg("path"),
      R"(Reads poses as an (n, 4, 4) float64 array: KITTI (12 numbers a line), TUM
("t x y z qx qy qz qw") or named ("NAME x y z qx qy qz qw"), detected from the first line.)");

  m.def(
      "write_trajectory",
      [](const std::string& path, const py::array& poses, const std::string& format,
         const std::optional<std::vector<double>>& stamps) {
        Trajectory t;
        t.format = parse_trajectory_format(format);
        t.poses = to_poses(poses, "poses");
        if (stamps) t.stamps = *stamps;
        if (t.format == TrajectoryFormat::tum && t.stamps.size() != t.poses.size())
          throw Error("stamps: the tum format needs one stamp per pose");
        if (t.format == TrajectoryFormat::named) throw Error("format: write kitti or tum");
        write_trajectory(path, t);
      },
      py::arg("path"), py::arg("poses"), py::arg("format") = "kitti", py::arg("stamps") = py::none(),
      R"(Writes (n, 4, 4) poses as "kitti" (12 numbers a line) or "tum" (needs stamps, one per pose).)");
}

}  // namespace gcmap::python
