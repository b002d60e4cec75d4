#include "gcmap/calibration/elevation_calibration.hpp"

#include <tbb/parallel_for.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <fstream>
#include <sstream>

#include "gcmap/core/deskew.hpp"
#include "gcmap/core/error.hpp"
#include "gcmap/core/gaussian_voxel_map.hpp"
#include "gcmap/core/se3.hpp"

namespace gcmap {
namespace {

constexpr double kDeg = M_PI / 180.0;
// Bins narrower than the 0.33 deg spacing of an HDL-64's upper beams, centred on whole tenths
// (beam tables are often round numbers: none sits on a border).
constexpr double kBin = 0.1 * kDeg, kLowest = -45.05 * kDeg;
constexpr int kBins = 901;
constexpr double kMaxOffset = 2.0 * kDeg;
constexpr double kHuber = 3.0;           // on the whitened point-to-plane distance
constexpr double kMinNormalZ = 0.9;      // level ground only (within 26 deg)
constexpr double kMaxWallNormalZ = 0.3;  // steep surfaces for levelling (within 17 deg of vertical)
// Cauchy scale on a steep normal's z: where a wall meets the ground or a corner, the neighbourhood
// spans both and the normal leans; those few must not tilt the scan.
constexpr double kWallCauchy = 0.1;
constexpr double kWallPrior = 100.0;     // points' worth of "no tilt" in the levelling
constexpr int kLevelIterations = 3;      // Gauss-Newton steps: a run may stand degrees off the vertical

int bin_of(double elevation) {
  if (!std::isfinite(elevation)) return -1;  // raw scans may hold NaN or infinite points
  const int b = static_cast<int>(std::floor((elevation - kLowest) / kBin));
  return b >= 0 && b < kBins ? b : -1;
}

// Points on the vertical axis (horizontal range h) have no elevation.
int bin_of(const Eigen::Vector3f& p, double h) { return h > 1e-3 ? bin_of(std::atan2(static_cast<double>(p.z()), h)) : -1; }
int bin_of(const Eigen::Vector3f& p) { return bin_of(p, std::hypot(p.x(), p.y())); }

// The point at horizontal range h turned about the horizontal axis across its azimuth by delta
// (given as its cosine and sine): elevation + delta, same range. A rotation in the beam's vertical
// plane needs no angles.
Eigen::Vector3f raised(const Eigen::Vector3f& p, double h, double cos_delta, double sin_delta) {
  if (h < 1e-6) return p;  // binned away from the axis, but deskewing moved it there
  const double z = p.z(), s = (h * cos_delta - z * sin_delta) / h;
  return {static_cast<float>(p.x() * s), static_cast<float>(p.y() * s), static_cast<float>(h * sin_delta + z * cos_delta)};
}
Eigen::Vector3f raised(const Eigen::Vector3f& p, double delta) {
  return raised(p, std::hypot(p.x(), p.y()), std::cos(delta), std::sin(delta));
}

// d p / d elevation: along the beam's vertical plane, as long as the horizontal range.
Eigen::Vector3d elevation_direction(const Eigen::Vector3d& p) {
  const double h = p.head<2>().norm();
  return {-p.z() * p.x() / h, -p.z() * p.y() / h, h};
}

struct Normals {
  std::vector<Eigen::Vector3d> n;
  std::vector<double> variance;  // along n
};

Normals level_normals(const GaussianVoxelMap& ground) {
  Normals out;
  out.n.resize(ground.num_voxels());
  out.variance.resize(ground.num_voxels());
  tbb::parallel_for(size_t{0}, ground.num_voxels(), [&](size_t v) {
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig;
    eig.computeDirect(ground.cov(static_cast<int>(v)).cast<double>());
    out.n[v] = eig.eigenvectors().col(0);
    out.variance[v] = std::abs(out.n[v].z()) >= kMinNormalZ ? eig.eigenvalues()(0) : -1.0;
  });
  return out;
}

}  // namespace

ElevationCalibration::ElevationCalibration() : offset_(kBins, 0.0) {}

double ElevationCalibration::offset(double elevation) const {
  const int b = bin_of(elevation);
  return b < 0 ? 0.0 : offset_[b];
}

void ElevationCalibration::drop_below(double threshold) {
  for (double& o : offset_)
    if (std::abs(o) < threshold) o = 0.0;
}

int ElevationCalibration::num_offsets() const {
  return static_cast<int>(std::count_if(offset_.begin(), offset_.end(), [](double o) { return o != 0.0; }));
}

double ElevationCalibration::largest_offset() const {
  double largest = 0.0;
  for (const double o : offset_) largest = std::max(largest, std::abs(o));
  return largest;
}

std::vector<int16_t> ElevationCalibration::bins(const PointCloud& cloud) {
  std::vector<int16_t> out(cloud.size(), -1);
  for (size_t i = 0; i < cloud.size(); ++i) out[i] = static_cast<int16_t>(bin_of(cloud.points[i]));
  return out;
}

bool ElevationCalibration::has_rings(const PointCloud& raw) {
  std::vector<int> count(kBins, 0);
  int total = 0;
  for (const Eigen::Vector3f& p : raw.points) {
    const double h = std::hypot(p.x(), p.y());
    const int b = h > 5.0 ? bin_of(p, h) : -1;
    if (b >= 0) ++count[b], ++total;
  }
  if (total < 1000) return false;
  // The span holding 98 % of the points, and how many of its bins hold 80 % of them.
  int first = 0, last = kBins - 1;
  for (int seen = 0; seen + count[first] <= total / 100; ++first) seen += count[first];
  for (int seen = 0; seen + count[last] <= total / 100; --last) seen += count[last];
  std::vector<int> sorted(count.begin() + first, count.begin() + last + 1);
  std::sort(sorted.begin(), sorted.end(), std::greater<>());
  int needed = 0;
  for (int held = 0; held < 0.8 * total && needed < static_cast<int>(sorted.size()); ++needed) held += sorted[needed];
  return needed < 0.4 * static_cast<double>(sorted.size());
}

CalibrationScan calibration_scan(PointCloud cloud, const Eigen::Isometry3d& T_world_sensor, const Vector6d* velocity) {
  CalibrationScan s;
  s.bins = ElevationCalibration::bins(cloud);
  s.T_world_sensor = T_world_sensor;
  if (velocity && cloud.has_times()) deskew(cloud, *velocity);
  cloud.times.clear();
  cloud.intensities.clear();
  s.cloud = std::move(cloud);
  return s;
}

void ElevationCalibration::correct(PointCloud& cloud) const {
  std::vector<Eigen::Vector2d> turn(kBins);  // cos, sin of each bin's offset
  for (int b = 0; b < kBins; ++b) turn[b] = {std::cos(offset_[b]), std::sin(offset_[b])};
  tbb::parallel_for(tbb::blocked_range<size_t>(0, cloud.size(), 4096), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i != r.end(); ++i) {
      const Eigen::Vector3f& p = cloud.points[i];
      const double h = std::hypot(p.x(), p.y());  // once: for the bin and the turn
      const int b = bin_of(p, h);
      if (b >= 0 && offset_[b] != 0.0) cloud.points[i] = raised(p, h, turn[b].x(), turn[b].y());
    }
  });
}

std::string ElevationCalibration::to_text() const {
  std::ostringstream s;
  s << "# gcmap elevation calibration: measured elevation (deg), offset to add (deg)\n";
  char line[64];
  for (int b = 0; b < kBins; ++b) {
    if (offset_[b] == 0.0) continue;
    std::snprintf(line, sizeof line, "%.2f %.5f\n", (kLowest + (b + 0.5) * kBin) / kDeg, offset_[b] / kDeg);
    s << line;
  }
  return s.str();
}

ElevationCalibration ElevationCalibration::parse(const std::string& text, const std::string& name) {
  ElevationCalibration c;
  std::istringstream in(text);
  std::string line;
  for (int n = 1; std::getline(in, line); ++n) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream fields(line);
    double elevation = NAN, offset = NAN;
    std::string rest;
    const bool ok = static_cast<bool>(fields >> elevation >> offset) && !(fields >> rest);
    const int b = ok && std::isfinite(elevation) ? bin_of(elevation * kDeg) : -1;
    if (b < 0 || !std::isfinite(offset) || std::abs(offset * kDeg) > kMaxOffset)
      throw Error(name + ": line " + std::to_string(n) +
                  ": expected \"elevation_deg offset_deg\" (elevation within +-45, offset within +-2)");
    c.offset_[b] = offset * kDeg;
  }
  return c;
}

ElevationCalibration ElevationCalibration::load(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw Error(path + ": cannot open the elevation calibration");
  std::ostringstream s;
  s << f.rdbuf();
  return parse(s.str(), path);
}

namespace {

// Per bin Gauss-Newton sums of one scan, or of all (added in scan order: the same result for any
// thread count).
struct BinSums {
  std::vector<double> info = std::vector<double>(kBins), grad = std::vector<double>(kBins);
  std::vector<double> range = std::vector<double>(kBins);  // horizontal, summed
  std::vector<int> count = std::vector<int>(kBins);
  void add(int b, double w, double j, double e, double h) {
    info[b] += w * j * j, grad[b] += w * j * e, range[b] += h, ++count[b];
  }
  void add(const BinSums& o) {
    for (int b = 0; b < kBins; ++b)
      info[b] += o.info[b], grad[b] += o.grad[b], range[b] += o.range[b], count[b] += o.count[b];
  }
};

using Corrected = std::function<Eigen::Vector3f(const CalibrationScan&, size_t)>;

BinSums total(const std::vector<BinSums>& per_scan) {
  BinSums all;
  for (const BinSums& b : per_scan) all.add(b);
  return all;
}

// Every point against the level ground that the near points of all scans make in the world.
BinSums world_sums(const std::vector<CalibrationScan>& scans, const Corrected& corrected, const CalibrationEstimate& o) {
  GaussianVoxelMap ground(o.voxel_resolution);
  for (const CalibrationScan& s : scans) {
    PointCloud near;
    for (size_t i = 0; i < s.cloud.size(); ++i) {
      if (s.cloud.points[i].norm() >= o.near_range) continue;
      near.points.push_back(corrected(s, i));
      near.covs.push_back(s.cloud.covs[i]);
    }
    ground.insert(near, s.T_world_sensor);
  }
  ground.finalize();
  const Normals normals = level_normals(ground);
  std::vector<BinSums> sums(scans.size());
  tbb::parallel_for(size_t{0}, scans.size(), [&](size_t k) {
    const CalibrationScan& s = scans[k];
    const Eigen::Matrix3d R = s.T_world_sensor.linear();
    for (size_t i = 0; i < s.cloud.size(); ++i) {
      if (s.bins[i] < 0) continue;
      const Eigen::Vector3d p = corrected(s, i).cast<double>(), q = s.T_world_sensor * p;
      if (p.head<2>().norm() < 1e-3) continue;
      const int v = ground.lookup(q.cast<float>());
      if (v < 0 || normals.variance[v] < 0.0) continue;
      const Eigen::Vector3d& n = normals.n[v];
      const double variance = normals.variance[v] + n.dot(R * s.cloud.covs[i].cast<double>() * R.transpose() * n);
      const double e = n.dot(ground.mean(v).cast<double>() - q), d = std::abs(e) / std::sqrt(variance);
      sums[k].add(s.bins[i], (d > kHuber ? kHuber / d : 1.0) / variance, n.dot(R * elevation_direction(p)), e, p.head<2>().norm());
    }
  });
  return total(sums);
}

// Normal equations of the small world rotation (about x and y) that levels the normals of the
// scan's steep surfaces: least squares on n_z + theta_x n_y - theta_y n_x.
struct TiltEquations {
  Eigen::Matrix2d A = Eigen::Matrix2d::Zero();
  Eigen::Vector2d b = Eigen::Vector2d::Zero();
};

TiltEquations wall_tilt(const CalibrationScan& s, const Eigen::Matrix3d& R_level = Eigen::Matrix3d::Identity()) {
  TiltEquations e;
  const Eigen::Matrix3d R = R_level * s.T_world_sensor.linear();
  for (const Eigen::Matrix3f& cov : s.cloud.covs) {
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3f> eig;
    eig.computeDirect(cov);
    const Eigen::Vector3d n = R * eig.eigenvectors().col(0).cast<double>();
    if (std::abs(n.z()) > kMaxWallNormalZ) continue;
    const double w = 1.0 / (1.0 + n.z() * n.z() / (kWallCauchy * kWallCauchy));
    const Eigen::Vector2d J(n.y(), -n.x());
    e.A += w * J * J.transpose(), e.b -= w * J * n.z();
  }
  return e;
}

// One Gauss-Newton step of every scan's levelling, positions re-integrated.
void level_step(std::vector<CalibrationScan>& scans, int window) {
  std::vector<TiltEquations> eq(scans.size());
  tbb::parallel_for(size_t{0}, scans.size(), [&](size_t k) { eq[k] = wall_tilt(scans[k]); });
  std::vector<Eigen::Isometry3d> before(scans.size());
  for (size_t k = 0; k < scans.size(); ++k) before[k] = scans[k].T_world_sensor;
  for (size_t k = 0; k < scans.size(); ++k) {
    // Walls along a street hold only the roll: the window adds the cross streets, and the prior
    // keeps a direction that no wall holds where it is.
    TiltEquations sum;
    sum.A = kWallPrior * Eigen::Matrix2d::Identity();
    const size_t first = k > static_cast<size_t>(window) ? k - window : 0, last = std::min(scans.size() - 1, k + window);
    for (size_t j = first; j <= last; ++j) sum.A += eq[j].A, sum.b += eq[j].b;
    const Eigen::Vector2d tilt = sum.A.ldlt().solve(sum.b);
    Eigen::Isometry3d& T = scans[k].T_world_sensor;
    T.linear() = so3_exp(Eigen::Vector3d(tilt.x(), tilt.y(), 0.0)) * before[k].linear();
    if (k > 0) {
      const Eigen::Isometry3d& T_prev = scans[k - 1].T_world_sensor;
      T.translation() = T_prev.translation() + T_prev.linear() * before[k - 1].linear().transpose() *
                                                   (before[k].translation() - before[k - 1].translation());
    }
  }
}

}  // namespace

void level_with_walls(std::vector<CalibrationScan>& scans, int window) {
  for (int it = 0; it < kLevelIterations; ++it) level_step(scans, window);
}

Eigen::Matrix3d levelling_rotation(const std::vector<CalibrationScan>& scans) {
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  for (int it = 0; it < kLevelIterations; ++it) {
    std::vector<TiltEquations> eq(scans.size());
    tbb::parallel_for(size_t{0}, scans.size(), [&](size_t k) { eq[k] = wall_tilt(scans[k], R); });
    TiltEquations sum;
    sum.A = kWallPrior * Eigen::Matrix2d::Identity();
    for (const TiltEquations& e : eq) sum.A += e.A, sum.b += e.b;
    const Eigen::Vector2d tilt = sum.A.ldlt().solve(sum.b);
    R = so3_exp(Eigen::Vector3d(tilt.x(), tilt.y(), 0.0)) * R;
  }
  return R;
}

ElevationCalibration ElevationCalibration::estimate(const std::vector<CalibrationScan>& scans,
                                                    const CalibrationEstimate& options) {
  ElevationCalibration c;
  const Corrected corrected = [&c](const CalibrationScan& s, size_t i) {
    return s.bins[i] >= 0 && c.offset_[s.bins[i]] != 0.0 ? raised(s.cloud.points[i], c.offset_[s.bins[i]]) : s.cloud.points[i];
  };
  for (int it = 0; it < options.iterations; ++it) {
    const BinSums sums = world_sums(scans, corrected, options);
    for (int b = 0; b < kBins; ++b) {
      // A beam whose ground lies mostly within near_range makes the reference itself: it cannot be
      // measured against it (and bends far ground little).
      if (sums.count[b] < options.min_points || sums.info[b] <= 0.0 || sums.range[b] < options.near_range * sums.count[b])
        continue;
      c.offset_[b] = std::clamp(c.offset_[b] + sums.grad[b] / sums.info[b], -kMaxOffset, kMaxOffset);
    }
  }
  return c;
}

}  // namespace gcmap
