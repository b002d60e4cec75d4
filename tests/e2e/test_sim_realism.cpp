#include <tbb/global_control.h>

#include <cstring>
#include <filesystem>
#include <map>
#include <set>
#include <unordered_map>

#include "gcmap/core/error.hpp"
#include "gcmap/io/file.hpp"
#include "gcmap/sim/simulator.hpp"
#include "test_util.hpp"

namespace gcmap {
namespace {

using sim::RealismConfig;

sim::SimulationConfig config(const std::string& scenario, int frames, std::optional<RealismConfig> realism = {}) {
  sim::SimulationConfig c;
  c.scenario = scenario;
  c.frames = frames;
  c.realism = realism;
  return c;
}

// Distances along the drive and speeds between frames (10 Hz).
std::vector<double> odometer(const std::vector<Eigen::Isometry3d>& poses) {
  std::vector<double> d(poses.size(), 0.0);
  for (size_t i = 1; i < poses.size(); ++i) d[i] = d[i - 1] + (poses[i].translation() - poses[i - 1].translation()).norm();
  return d;
}

TEST(SimRealism, CityIsAKittiScaleDriveWithStopsSlopesAndRevisits) {
  const sim::Simulator city(config("city", 0));
  const auto& p = city.poses();
  EXPECT_GT(p.size(), 4000u);
  EXPECT_LT(p.size(), 5000u);
  const std::vector<double> odo = odometer(p);
  EXPECT_NEAR(odo.back(), 3700.0, 150.0);
  size_t stationary = 0;
  double max_speed = 0.0, z_min = 1e9, z_max = -1e9;
  for (size_t i = 1; i < p.size(); ++i) {
    const double v = (odo[i] - odo[i - 1]) / 0.1;
    max_speed = std::max(max_speed, v);
    stationary += v < 1e-6;
    z_min = std::min(z_min, p[i].translation().z()), z_max = std::max(z_max, p[i].translation().z());
  }
  EXPECT_LE(max_speed, 15.0 + 1e-6);
  EXPECT_GT(max_speed, 12.0);
  EXPECT_GT(stationary, 50u);     // stops at intersections
  EXPECT_GT(z_max - z_min, 8.0);  // slopes
  // Revisits more than 2 km of driving apart, within a few metres, in both directions.
  bool same = false, opposite = false;
  for (size_t i = 0; i < p.size(); i += 2) {
    for (size_t j = i; j < p.size(); j += 2) {
      if (odo[j] - odo[i] < 2000.0 || (p[i].translation() - p[j].translation()).norm() > 5.0) continue;
      const double c = p[i].linear().col(0).dot(p[j].linear().col(0));
      same |= c > 0.9, opposite |= c < -0.9;
    }
  }
  EXPECT_TRUE(same);
  EXPECT_TRUE(opposite);
}

TEST(SimRealism, HighwayAndForestDriveAtTheirSpeeds) {
  const sim::Simulator highway(config("highway", 0));
  const std::vector<double> odo = odometer(highway.poses());
  EXPECT_NEAR(odo.back(), 2100.0, 150.0);
  for (size_t i = 1; i < odo.size(); ++i) {
    ASSERT_GE(odo[i] - odo[i - 1], 2.45) << "frame " << i;
    ASSERT_LE(odo[i] - odo[i - 1], 3.05) << "frame " << i;
  }
  const sim::Simulator forest(config("forest", 0));
  const std::vector<double> f = odometer(forest.poses());
  for (size_t i = 1; i < f.size(); ++i) ASSERT_LE(f[i] - f[i - 1], 0.75) << "frame " << i;
  EXPECT_NEAR((forest.poses().front().translation() - forest.poses().back().translation()).head<2>().norm(), 60.0, 15.0);
}

// Every file of a simulation folder, by relative path.
std::map<std::string, std::string> folder_bytes(const std::filesystem::path& dir) {
  std::map<std::string, std::string> files;
  for (const auto& e : std::filesystem::recursive_directory_iterator(dir))
    if (e.is_regular_file()) files[std::filesystem::relative(e.path(), dir).string()] = read_file(e.path().string());
  return files;
}

TEST(SimRealism, SameSeedSameBytesForAnyThreadCount) {
  for (const char* scenario : {"city", "highway", "forest"}) {
    test::TempDir a, b, c;
    sim::write_simulation(a.path.string(), config(scenario, 2));
    sim::write_simulation(b.path.string(), config(scenario, 2));
    {
      tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
      sim::write_simulation(c.path.string(), config(scenario, 2));
    }
    const auto fa = folder_bytes(a.path);
    EXPECT_EQ(fa.size(), 2u * 3u + 4u) << scenario;  // velodyne, point_times, labels; poses, poses_world, times, scenario.json
    EXPECT_TRUE(fa == folder_bytes(b.path)) << scenario;
    EXPECT_TRUE(fa == folder_bytes(c.path)) << scenario;
  }
}

TEST(SimRealism, AnExcerptIsTheStartOfTheWholeDrive) {
  const PointCloud whole = sim::Simulator(config("city", 0)).scan(4), excerpt = sim::Simulator(config("city", 5)).scan(4);
  ASSERT_EQ(whole.size(), excerpt.size());
  EXPECT_EQ(std::memcmp(whole.points.data(), excerpt.points.data(), whole.size() * sizeof(Eigen::Vector3f)), 0);
  EXPECT_EQ(whole.labels, excerpt.labels);
}

TEST(SimRealism, IdealWritesNoSidecarsAndNoErrors) {
  test::TempDir dir;
  sim::SimulationConfig cfg = config("city", 2, RealismConfig::none());
  cfg.noise = 0.0;
  sim::write_simulation(dir.path.string(), cfg);
  EXPECT_TRUE(std::filesystem::exists(dir / "velodyne/000001.bin"));
  EXPECT_FALSE(std::filesystem::exists(dir / "point_times"));
  EXPECT_FALSE(std::filesystem::exists(dir / "labels"));
  // Without noise or errors every point lies on the world: its ray ends there.
  const sim::Simulator s(cfg);
  const PointCloud scan = s.scan(1);
  const Eigen::Isometry3f T = s.poses()[1].cast<float>();
  for (size_t i = 0; i < scan.size(); i += 97) {
    sim::Hit hit;
    const float r = scan.points[i].norm();
    ASSERT_TRUE(s.world().raycast(T.translation(), T.linear() * scan.points[i] / r, 200.f, hit));
    ASSERT_NEAR(hit.range, r, 1e-2f);  // the ground is found to 2 mm vertically
  }
  EXPECT_EQ(sim::parse_realism("labels,curbs").to_string(), "labels,curbs");
  EXPECT_THROW(sim::parse_realism("labels,wobble"), Error);
}

// Highway frame 5: a straight road at 25-30 m/s. The same rays with and without distortion.
TEST(SimRealism, DistortionDisplacesLatePointsBySpeedTimesTime) {
  RealismConfig distorted = RealismConfig::none(), still = RealismConfig::none();
  distorted.motion_distortion = distorted.labels = still.labels = true;
  sim::SimulationConfig cd = config("highway", 10, distorted), cs = config("highway", 10, still);
  cd.noise = cs.noise = 0.0;
  const sim::Simulator sd(cd), ss(cs);
  const size_t frame = 5;
  std::vector<uint32_t> id_d, id_s;
  const PointCloud d = sd.scan(frame, &id_d), u = ss.scan(frame, &id_s);
  ASSERT_TRUE(d.has_times());
  EXPECT_FALSE(u.has_times());
  std::unordered_map<uint32_t, size_t> undistorted;
  for (size_t i = 0; i < id_s.size(); ++i) undistorted[id_s[i]] = i;
  const Eigen::Isometry3d& T0 = sd.poses()[frame];
  const double speed = (sd.poses()[frame + 1].translation() - T0.translation()).norm() / 0.1;
  size_t late = 0, early = 0;
  for (size_t i = 0; i < d.size(); ++i) {
    const auto it = undistorted.find(id_d[i]);
    if (it == undistorted.end() || d.labels[i] != sim::kRoad || u.labels[it->second] != sim::kRoad) continue;
    const double t = d.times[i];
    ASSERT_GE(t, 0.0);
    ASSERT_LT(t, 0.1);
    const Eigen::Vector3d pd = d.points[i].cast<double>(), pu = u.points[it->second].cast<double>();
    // The late firing comes from a sensor speed * t further on: the ground it hits is as far ahead.
    const Eigen::Vector3d moved = T0.inverse() * sd.pose_at(frame, t).translation();
    if (t > 0.08 && pu.norm() < 25.0) {  // farther, the terrain's curvature shows at grazing angles
      ++late;
      EXPECT_NEAR(moved.norm(), speed * t, 0.02 * speed * t);
      EXPECT_GT((T0.inverse() * sd.pose_at(frame, t) * pd - pu).norm(), 0.9 * speed * t);
      EXPECT_LT((T0.inverse() * sd.pose_at(frame, t) * pd - pu - moved).norm(), 0.05);
    } else if (t < 0.002) {
      ++early;
      EXPECT_LT((pd - pu).norm(), 0.01);
    }
  }
  EXPECT_GT(late, 1000u);
  EXPECT_GT(early, 100u);
  EXPECT_GT(speed, 24.9);
}

// Every point labelled moving lies on the box of its mover at its firing time; no other point does.
TEST(SimRealism, LabelsMarkExactlyThePointsOnMovingObjects) {
  RealismConfig r = RealismConfig::none();
  r.motion_distortion = r.moving_objects = r.labels = true;
  sim::SimulationConfig cfg = config("city", 12, r);
  cfg.noise = 0.0;
  const sim::Simulator s(cfg);
  size_t moving = 0;
  for (size_t frame : {0u, 6u, 11u}) {
    const PointCloud scan = s.scan(frame);
    ASSERT_EQ(scan.labels.size(), scan.size());
    const Eigen::Vector3d origin = s.poses()[frame].translation();
    std::vector<size_t> near;
    std::vector<Eigen::Vector3d> centers;
    for (size_t m = 0; m < s.traffic().size(); ++m) {
      const Eigen::Vector3d c = s.traffic().state(m, frame * 0.1, s.world()).center.cast<double>();
      if ((c - origin).norm() < 140.0) near.push_back(m), centers.push_back(c);
    }
    for (size_t i = 0; i < scan.size(); ++i) {
      const double t = scan.times[i];
      const Eigen::Vector3d w = s.pose_at(frame, t) * scan.points[i].cast<double>();
      // Margin of each box that the point is inside of (negative: outside).
      auto inside = [&](size_t m) {
        const sim::MoverState st = s.traffic().state(m, frame * 0.1 + t, s.world());
        const Eigen::Vector3d q = w - st.center.cast<double>();
        const Eigen::Vector3d l(std::cos(st.yaw) * q.x() + std::sin(st.yaw) * q.y(),
                                -std::sin(st.yaw) * q.x() + std::cos(st.yaw) * q.y(), q.z());
        return (s.traffic().mover(m).half.cast<double>() - l.cwiseAbs()).minCoeff();
      };
      const uint32_t cls = scan.labels[i] & 0xffff, instance = scan.labels[i] >> 16;
      if (cls >= 252 && cls <= 259) {
        ++moving;
        ASSERT_GE(instance, 1u);
        ASSERT_EQ(cls, s.traffic().mover(instance - 1).label);
        ASSERT_GT(inside(instance - 1), -0.01) << "frame " << frame << " point " << i;
      } else {
        for (size_t k = 0; k < near.size(); ++k) {  // movers cover less than 2 m in a sweep
          if ((w - centers[k]).norm() < 10.0) ASSERT_LT(inside(near[k]), 0.01) << "frame " << frame << " point " << i;
        }
      }
    }
  }
  EXPECT_GT(moving, 200u);
}

TEST(SimRealism, SolidStateAndHighResolutionSensors) {
  sim::SimulationConfig cfg = config("forest", 3);
  cfg.sensor = "avia";
  const sim::Simulator avia(cfg);
  const PointCloud a0 = avia.scan(0), a1 = avia.scan(1);
  EXPECT_GT(a0.size(), 10000u);
  // Within the field of view, times spread over the sweep.
  float t_max = 0.f;
  for (size_t i = 0; i < a0.size(); ++i) {
    const Eigen::Vector3f& p = a0.points[i];
    ASSERT_LT(std::abs(std::atan2(p.y(), p.x())), 36.5f * M_PI / 180.f);
    ASSERT_LT(std::abs(std::asin(p.z() / p.norm())), 39.5f * M_PI / 180.f);
    t_max = std::max(t_max, a0.times[i]);
  }
  EXPECT_GT(t_max, 0.095f);
  // Non-repetitive: the second sweep's directions fall between the first's.
  auto cells = [](const PointCloud& c) {
    std::set<int> s;
    for (const auto& p : c.points) {
      const Eigen::Vector3f d = p.normalized();
      s.insert(static_cast<int>(std::floor(std::atan2(d.y(), d.x()) * 300)) * 10000 +
               static_cast<int>(std::floor(std::asin(d.z()) * 300)));
    }
    return s;
  };
  const std::set<int> c0 = cells(a0), c1 = cells(a1);
  std::set<int> both = c0;
  both.insert(c1.begin(), c1.end());
  EXPECT_GT(both.size(), c0.size() * 13 / 10);

  cfg.sensor = "os1-128";
  cfg.scenario = "city";
  const sim::Simulator os(cfg);
  EXPECT_EQ(os.sensor().rays_per_group(), 128);
  EXPECT_GT(os.scan(1).size(), 60000u);
  cfg.sensor = "hdl32";
  EXPECT_THROW(sim::Simulator{cfg}, Error);
}

// A person walking with the sensor in hand: walking pace, a gait's bounce, glances aside at up to
// about 190 deg/s; the Mid-360-like sensor sees all around, from 7 deg below the horizon to 52 above.
TEST(SimRealism, HandheldWalksBouncesAndGlancesWithAMid360) {
  sim::SimulationConfig cfg = config("handheld", 450, sim::parse_realism("motion_distortion"));
  cfg.sensor = "mid360";
  const sim::Simulator sim(cfg);
  double max_rate_deg = 0.0, length = 0.0, max_accel = 0.0;
  std::vector<double> z;
  for (double t = 0.0; t < 44.0; t += 0.01) {
    const Eigen::Isometry3d a = sim.pose_at_time(t), b = sim.pose_at_time(t + 0.01);
    max_rate_deg = std::max(max_rate_deg, rotation_angle(a.inverse() * b) / 0.01 * 180.0 / M_PI);
    length += (b.translation() - a.translation()).norm();
    z.push_back(a.translation().z());
    if (t > 0.0)
      max_accel = std::max(max_accel, (b.translation() - 2.0 * a.translation() + sim.pose_at_time(t - 0.01).translation()).norm() / 1e-4);
  }
  std::printf("handheld: fastest turn %.0f deg/s, mean speed %.2f m/s, largest acceleration %.1f m/s^2\n", max_rate_deg,
              length / 44.0, max_accel);
  // A walker's hand: the gait's bounce and the stops, no jolt (a speed that steps, a path that
  // steps back where a straight meets a corner: 20-190 m/s^2 to an IMU).
  EXPECT_LT(max_accel, 10.0);
  EXPECT_GT(max_rate_deg, 150.0);
  EXPECT_LT(max_rate_deg, 260.0);
  EXPECT_GT(length / 44.0, 0.7);  // waits at crossings included
  EXPECT_LT(length / 44.0, 1.5);
  // The bounce: the height less its one-second mean, while walking (from 10 s on).
  double bounce = 0.0;
  for (size_t i = 1050; i + 50 < z.size(); ++i) {
    double mean = 0.0;
    for (size_t j = i - 50; j < i + 50; ++j) mean += z[j] / 100.0;
    bounce = std::max(bounce, std::abs(z[i] - mean));
  }
  std::printf("handheld: bounce %.3f m\n", bounce);
  EXPECT_GT(bounce, 0.01);
  EXPECT_LT(bounce, 0.06);
  const PointCloud scan = sim.scan(100);
  EXPECT_GT(scan.size(), 5000u);
  ASSERT_TRUE(scan.has_times());
  std::set<int> octants;
  float t_max = 0.f;
  for (size_t i = 0; i < scan.size(); ++i) {
    const Eigen::Vector3f d = scan.points[i].normalized();
    const float el = std::asin(d.z()) * 180.f / static_cast<float>(M_PI);
    ASSERT_GT(el, -7.5f);
    ASSERT_LT(el, 52.5f);
    octants.insert(std::min(7, static_cast<int>(std::floor((std::atan2(d.y(), d.x()) + M_PI) / (M_PI / 4)))));
    t_max = std::max(t_max, scan.times[i]);
  }
  EXPECT_EQ(octants.size(), 8u);
  EXPECT_GT(t_max, 0.095f);
}

}  // namespace
}  // namespace gcmap
