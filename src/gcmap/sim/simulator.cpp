#include "gcmap/sim/simulator.hpp"

#include <spdlog/spdlog.h>
#include <tbb/parallel_for.h>

#include <cmath>
#include <filesystem>
#include <random>

#include "gcmap/core/error.hpp"
#include "gcmap/io/file.hpp"
#include "gcmap/io/json.hpp"
#include "gcmap/io/trajectory_io.hpp"

namespace gcmap::sim {

SensorModel sensor_model(const std::string& name) {
  SensorModel s;
  s.name = name;
  if (name == "hdl64") {
    // HDL-64E: upper block +2 to -8.33 deg in 1/3 deg steps, lower block -8.83 to -24.33 in 1/2.
    for (int k = 0; k < 32; ++k) s.elevations_deg.push_back(2.0f - k / 3.0f);
    for (int k = 0; k < 32; ++k) s.elevations_deg.push_back(-8.83f - k * 0.5f);
    s.azimuth_steps = 1800;
  } else if (name == "vlp16") {
    for (int k = 0; k < 16; ++k) s.elevations_deg.push_back(-15.0f + 2.0f * k);
    s.azimuth_steps = 1800;
    s.max_range = 100.0f;
  } else if (name == "os1-64") {
    for (int k = 0; k < 64; ++k) s.elevations_deg.push_back(-22.5f + 45.0f * k / 63.0f);
    s.azimuth_steps = 1024;
  } else {
    throw Error("--sensor: expected hdl64, vlp16 or os1-64, got '" + name + "'");
  }
  return s;
}

Scenario make_scenario(const SimulationConfig& config) {
  Scenario s;
  s.name = config.scenario;
  auto wp = [&](std::initializer_list<std::pair<float, float>> pts) {
    for (auto [x, y] : pts) s.waypoints.emplace_back(x, y);
  };
  if (s.name == "loop") {
    // A 600 m loop back to the start, then a long detour that comes back to a corner of the first
    // loop and drives one of its streets in the opposite direction: about 1.55 km.
    s.block = 50.f;
    wp({{0, 0}, {3, 0}, {3, 3}, {0, 3}, {0, 0}, {0, -2}, {5, -2}, {5, 4}, {3, 4}, {3, 3}, {3, 0}});
    s.frames = 1500;
    s.description = "1.55 km through a street grid: a 600 m loop, a 800 m detour, an opposite-direction revisit";
  } else if (s.name == "small") {
    s.block = 40.f;
    wp({{0, 0}, {1, 0}, {1, 1}, {0, 1}, {0, 0}, {0.25f, 0}});
    s.frames = 150;
    s.description = "one 160 m block loop with a revisit of the start";
  } else if (s.name == "corridor") {
    s.block = 50.f;
    wp({{0, 0}, {10, 0}});
    s.frames = 500;
    s.feature_poor = true;
    s.description = "a 500 m straight street between flat facades: degenerate along the street";
  } else {
    throw Error("--scenario: expected loop, small or corridor, got '" + s.name + "'");
  }
  if (config.frames > 0) s.frames = config.frames;
  if (s.frames < 2) throw Error("--frames: need at least 2 frames");
  return s;
}

namespace {

// Dense centre-line path through the waypoints with rounded corners, shifted to the right lane.
std::vector<Eigen::Vector2f> lane_path(const Scenario& s, double& length) {
  std::vector<Eigen::Vector2f> pts;
  const float radius = 9.f, lane = 2.f, step = 0.05f;
  const size_t n = s.waypoints.size();
  for (size_t k = 0; k + 1 < n; ++k) {
    const Eigen::Vector2f a = s.waypoints[k] * s.block, b = s.waypoints[k + 1] * s.block;
    const Eigen::Vector2f d = (b - a).normalized();
    const float len = (b - a).norm();
    const float cut_in = (k > 0) ? radius : 0.f;
    const float cut_out = (k + 2 < n) ? radius : 0.f;
    for (float t = cut_in; t <= len - cut_out; t += step) pts.push_back(a + t * d);
    if (k + 2 < n) {
      // Quadratic Bezier through the corner.
      const Eigen::Vector2f c = b, p0 = b - radius * d;
      const Eigen::Vector2f d2 = (s.waypoints[k + 2] * s.block - b).normalized();
      const Eigen::Vector2f p2 = b + radius * d2;
      for (float t = 0.f; t < 1.f; t += step / (1.6f * radius)) {
        pts.push_back((1 - t) * (1 - t) * p0 + 2 * (1 - t) * t * c + t * t * p2);
      }
    }
  }
  // Right-lane offset along the local normal.
  std::vector<Eigen::Vector2f> out(pts.size());
  for (size_t i = 0; i < pts.size(); ++i) {
    const Eigen::Vector2f t = (pts[std::min(i + 1, pts.size() - 1)] - pts[i > 0 ? i - 1 : 0]).normalized();
    out[i] = pts[i] + lane * Eigen::Vector2f(t.y(), -t.x());
  }
  length = 0.0;
  for (size_t i = 1; i < out.size(); ++i) length += (out[i] - out[i - 1]).norm();
  return out;
}

}  // namespace

Simulator::Simulator(const SimulationConfig& config)
    : config_(config),
      scenario_(make_scenario(config)),
      sensor_(sensor_model(config.sensor)),
      world_([&] {
        Eigen::Vector2f lo = scenario_.waypoints[0], hi = lo;
        for (const auto& w : scenario_.waypoints) {
          lo = lo.cwiseMin(w);
          hi = hi.cwiseMax(w);
        }
        return World(config.seed, scenario_.block, Eigen::Vector2i(std::floor(lo.x()) - 1, std::floor(lo.y()) - 1),
                     Eigen::Vector2i(std::ceil(hi.x()) + 1, std::ceil(hi.y()) + 1), scenario_.feature_poor);
      }()) {
  if (!(config.noise >= 0.0) || config.noise > 1.0) throw Error("--noise: must be in [0, 1] m");
  const std::vector<Eigen::Vector2f> path = lane_path(scenario_, length_);
  std::vector<double> arc(path.size(), 0.0);
  for (size_t i = 1; i < path.size(); ++i) arc[i] = arc[i - 1] + (path[i] - path[i - 1]).norm();
  const int n = scenario_.frames;
  size_t seg = 0;
  for (int k = 0; k < n; ++k) {
    const double s = length_ * k / (n - 1);
    while (seg + 2 < path.size() && arc[seg + 1] < s) ++seg;
    const double f = std::clamp((s - arc[seg]) / std::max(arc[seg + 1] - arc[seg], 1e-9), 0.0, 1.0);
    const Eigen::Vector2f p = path[seg] + static_cast<float>(f) * (path[seg + 1] - path[seg]);
    // Heading from a short look-ahead/behind chord smooths the polyline's kinks.
    const size_t a = seg >= 20 ? seg - 20 : 0, b = std::min(seg + 21, path.size() - 1);
    const Eigen::Vector2f t = (path[b] - path[a]).normalized();
    // The vehicle follows the terrain: z along the ground normal, x along the heading.
    const Eigen::Vector2f g = world_.ground_gradient(p.x(), p.y());
    const Eigen::Vector3d z = Eigen::Vector3d(-g.x(), -g.y(), 1.0).normalized();
    Eigen::Vector3d x(t.x(), t.y(), 0.0);
    x = (x - x.dot(z) * z).normalized();
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear().col(0) = x;
    T.linear().col(1) = z.cross(x);
    T.linear().col(2) = z;
    T.translation() = Eigen::Vector3d(p.x(), p.y(), world_.ground_height(p.x(), p.y()) + 1.73);
    poses_.push_back(T);
  }
}

PointCloud Simulator::scan(size_t frame) const {
  const Eigen::Isometry3d& T = poses_.at(frame);
  const Eigen::Matrix3f R = T.linear().cast<float>();
  const Eigen::Vector3f o = T.translation().cast<float>();
  const int beams = static_cast<int>(sensor_.elevations_deg.size());
  const int cols = sensor_.azimuth_steps;
  std::vector<Eigen::Vector3f> pts(static_cast<size_t>(beams) * cols);
  std::vector<float> inten(pts.size());
  std::vector<char> valid(pts.size(), 0);
  tbb::parallel_for(0, cols, [&](int c) {
    // One generator per column and frame: deterministic for any thread count.
    std::mt19937 rng(static_cast<uint32_t>(config_.seed * 1000003u + frame * 7919u + c));
    std::normal_distribution<float> noise(0.f, static_cast<float>(config_.noise));
    std::uniform_real_distribution<float> u(0.f, 1.f);
    const float az = 2.f * static_cast<float>(M_PI) * c / cols;
    for (int b = 0; b < beams; ++b) {
      const float el = sensor_.elevations_deg[b] * static_cast<float>(M_PI) / 180.f;
      const Eigen::Vector3f d_local(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el));
      Hit hit;
      const float drop = u(rng);
      const float n = config_.noise > 0 ? noise(rng) : 0.f;
      if (!world_.raycast(o, R * d_local, sensor_.max_range, hit)) continue;
      if (drop < sensor_.dropout) continue;
      const float range = hit.range + n;
      if (range < sensor_.min_range || range > sensor_.max_range) continue;
      const size_t i = static_cast<size_t>(c) * beams + b;
      pts[i] = range * d_local;
      inten[i] = std::clamp(hit.reflectivity * (1.f - range / 200.f), 0.f, 1.f);
      valid[i] = 1;
    }
  });
  PointCloud cloud;
  for (size_t i = 0; i < pts.size(); ++i) {
    if (!valid[i]) continue;
    cloud.points.push_back(pts[i]);
    cloud.intensities.push_back(inten[i]);
  }
  return cloud;
}

size_t write_simulation(const std::string& dir, const SimulationConfig& config, bool quiet) {
  Simulator sim(config);
  namespace fs = std::filesystem;
  std::error_code ec;
  fs::create_directories(fs::path(dir) / "velodyne", ec);
  if (ec) throw Error(dir + ": cannot create output folder (" + ec.message() + ")");
  const Eigen::Isometry3d T0_inv = sim.poses().front().inverse();
  Trajectory gt;
  gt.format = TrajectoryFormat::kitti;
  size_t total = 0;
  for (size_t k = 0; k < sim.num_frames(); ++k) {
    const PointCloud c = sim.scan(k);
    total += c.size();
    std::vector<float> buf(c.size() * 4);
    for (size_t i = 0; i < c.size(); ++i) {
      buf[4 * i + 0] = c.points[i].x();
      buf[4 * i + 1] = c.points[i].y();
      buf[4 * i + 2] = c.points[i].z();
      buf[4 * i + 3] = c.intensities[i];
    }
    char name[32];
    std::snprintf(name, sizeof(name), "%06zu.bin", k);
    write_file_atomic((fs::path(dir) / "velodyne" / name).string(), [&](std::ostream& out) {
      out.write(reinterpret_cast<const char*>(buf.data()), static_cast<std::streamsize>(buf.size() * sizeof(float)));
    });
    gt.poses.push_back(T0_inv * sim.poses()[k]);
    if (!quiet && (k % 50 == 0)) spdlog::info("simulated frame {}/{} ({} points)", k, sim.num_frames(), c.size());
  }
  write_trajectory((fs::path(dir) / "poses.txt").string(), gt);
  write_file_atomic((fs::path(dir) / "times.txt").string(), [&](std::ostream& out) {
    char line[32];
    for (size_t k = 0; k < sim.num_frames(); ++k) {
      std::snprintf(line, sizeof(line), "%.6e\n", 0.1 * k);
      out << line;
    }
  });
  Json j = Json::object();
  j["scenario"] = sim.scenario().name;
  j["description"] = sim.scenario().description;
  j["frames"] = sim.num_frames();
  j["seed"] = static_cast<unsigned long>(config.seed);
  j["sensor"] = config.sensor;
  j["range_noise_sigma"] = config.noise;
  j["path_length_m"] = sim.path_length();
  j["rate_hz"] = 10.0;
  j["mean_points_per_scan"] = static_cast<double>(total) / sim.num_frames();
  j["motion_distortion"] = false;
  j["poses"] = "poses.txt: ground-truth sensor poses, KITTI 3x4, first pose identity";
  write_file_atomic((fs::path(dir) / "scenario.json").string(), [&](std::ostream& out) { out << j.dump() << "\n"; });
  return total;
}

}  // namespace gcmap::sim
