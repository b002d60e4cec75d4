#include "gcmap/io/trajectory_io.hpp"

#include <charconv>
#include <cmath>
#include <cstdio>
#include <sstream>

#include "gcmap/core/error.hpp"
#include "gcmap/core/se3.hpp"
#include "gcmap/io/file.hpp"

namespace gcmap {

namespace {

std::vector<std::string> tokens(const std::string& line) {
  std::vector<std::string> out;
  std::istringstream ss(line);
  std::string t;
  while (ss >> t) out.push_back(t);
  return out;
}

bool to_double(const std::string& s, double& v) {
  const auto r = std::from_chars(s.data(), s.data() + s.size(), v);
  return r.ec == std::errc() && r.ptr == s.data() + s.size();
}

// The rotation block of a 3x4 [R t] read from a file must be one, up to the file's rounding: a
// garbage matrix would otherwise become a NaN or arbitrary pose.
bool rotation_block_ok(const double* m) {
  Eigen::Matrix3d R;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) R(r, c) = m[r * 4 + c];
  return (R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() < 1e-2 && R.determinant() > 0;
}

// Beyond this a position is garbage, not a place on or near Earth (its radius is 6.4e6 m); it
// would overflow the metrics' sums and squares into inf or NaN.
constexpr double kMaxTranslation = 1e7;  // m

void check_translation(const Eigen::Isometry3d& T, const std::string& where) {
  if (T.translation().cwiseAbs().maxCoeff() > kMaxTranslation)
    throw Error(where + "translation beyond 1e7 m (10,000 km): not a position");
}

Eigen::Isometry3d pose_from_rows(const double* m) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) T.linear()(r, c) = m[r * 4 + c];
    T.translation()(r) = m[r * 4 + 3];
  }
  return normalized(T);
}

}  // namespace

TrajectoryFormat parse_trajectory_format(const std::string& name) {
  if (name == "kitti") return TrajectoryFormat::kitti;
  if (name == "tum") return TrajectoryFormat::tum;
  throw Error("--format: expected kitti or tum, got '" + name + "'");
}

Trajectory read_trajectory(const std::string& path) { return parse_trajectory(read_file(path), path); }

Trajectory parse_trajectory(std::string_view text, const std::string& path) {
  std::istringstream in{std::string(text)};
  Trajectory traj;
  bool detected = false;
  std::string line;
  size_t line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    auto tok = tokens(line);
    if (tok.empty() || tok[0][0] == '#') continue;
    const std::string where = path + ":" + std::to_string(line_no) + ": ";
    double first = 0;
    const bool first_numeric = to_double(tok[0], first);
    TrajectoryFormat fmt;
    if (tok.size() == 12 && first_numeric) fmt = TrajectoryFormat::kitti;
    else if (tok.size() == 8 && first_numeric) fmt = TrajectoryFormat::tum;
    else if (tok.size() == 8) fmt = TrajectoryFormat::named;
    else
      throw Error(where + "expected 12 numbers (KITTI), 't x y z qx qy qz qw' (TUM) or 'NAME x y z qx qy qz qw', got " +
                  std::to_string(tok.size()) + " fields");
    if (!detected) {
      traj.format = fmt;
      detected = true;
    } else if (fmt != traj.format) {
      throw Error(where + "line format differs from the first line");
    }
    double v[12];
    const size_t start = fmt == TrajectoryFormat::kitti ? 0 : 1;
    for (size_t k = start; k < tok.size(); ++k) {
      if (!to_double(tok[k], v[k - start]) || !std::isfinite(v[k - start]))
        throw Error(where + "bad or non-finite number '" + tok[k] + "'");
    }
    if (fmt == TrajectoryFormat::kitti) {
      if (!rotation_block_ok(v)) throw Error(where + "the 3x3 block is not a rotation matrix");
      traj.poses.push_back(pose_from_rows(v));
      check_translation(traj.poses.back(), where);
    } else {
      const double qn = std::sqrt(v[3] * v[3] + v[4] * v[4] + v[5] * v[5] + v[6] * v[6]);
      if (qn < 1e-6) throw Error(where + "zero quaternion");
      if (!std::isfinite(qn)) throw Error(where + "quaternion too large to normalize");
      traj.poses.push_back(pose_from_xyz_quat(v));
      check_translation(traj.poses.back(), where);
      if (fmt == TrajectoryFormat::tum) {
        if (!std::isfinite(first)) throw Error(where + "non-finite timestamp");
        traj.stamps.push_back(first);
      } else {
        traj.names.push_back(tok[0]);
      }
    }
  }
  if (traj.poses.empty()) throw Error(path + ": no poses");
  return traj;
}

void write_trajectory(const std::string& path, const Trajectory& traj) {
  write_file_atomic(path, [&](std::ostream& out) {
    char buf[512];
    for (size_t i = 0; i < traj.size(); ++i) {
      const Eigen::Isometry3d& T = traj.poses[i];
      if (traj.format == TrajectoryFormat::kitti) {
        const Eigen::Matrix<double, 3, 4> M = T.matrix().topRows<3>();
        std::snprintf(buf, sizeof(buf), "%.9g %.9g %.9g %.9g %.9g %.9g %.9g %.9g %.9g %.9g %.9g %.9g\n", M(0, 0), M(0, 1),
                      M(0, 2), M(0, 3), M(1, 0), M(1, 1), M(1, 2), M(1, 3), M(2, 0), M(2, 1), M(2, 2), M(2, 3));
      } else {
        double v[7];
        pose_to_xyz_quat(T, v);
        const std::string head = traj.format == TrajectoryFormat::tum
                                     ? [&] { char s[64]; std::snprintf(s, sizeof(s), "%.9f", i < traj.stamps.size() ? traj.stamps[i] : double(i)); return std::string(s); }()
                                     : (i < traj.names.size() ? traj.names[i] : std::string("v").append(std::to_string(i)));
        std::snprintf(buf, sizeof(buf), "%s %.9g %.9g %.9g %.9g %.9g %.9g %.9g\n", head.c_str(), v[0], v[1], v[2], v[3], v[4],
                      v[5], v[6]);
      }
      out << buf;
    }
  });
}

Eigen::Isometry3d read_kitti_calib_tr(const std::string& path) { return parse_kitti_calib_tr(read_file(path), path); }

Eigen::Isometry3d parse_kitti_calib_tr(std::string_view text, const std::string& path) {
  std::istringstream in{std::string(text)};
  std::string line;
  while (std::getline(in, line)) {
    auto tok = tokens(line);
    if (tok.size() == 13 && (tok[0] == "Tr:" || tok[0] == "Tr_velo_cam:" || tok[0] == "Tr_velo_to_cam:")) {
      double v[12];
      for (int k = 0; k < 12; ++k)
        if (!to_double(tok[k + 1], v[k]) || !std::isfinite(v[k])) throw Error(path + ": bad number in Tr");
      if (!rotation_block_ok(v)) throw Error(path + ": the 3x3 block of Tr is not a rotation matrix");
      const Eigen::Isometry3d Tr = pose_from_rows(v);
      check_translation(Tr, path + ": Tr: ");
      return Tr;
    }
  }
  throw Error(path + ": no 'Tr:' line");
}

}  // namespace gcmap
