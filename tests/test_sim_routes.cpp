// Several routes through one simulated world: ground truth across sessions.
#include <random>

#include "gcmap/core/error.hpp"
#include "gcmap/io/trajectory_io.hpp"
#include "gcmap/sim/simulator.hpp"
#include "test_util.hpp"

namespace gcmap {
namespace {

sim::SimulationConfig route_config(const char* scenario, int route, int frames) {
  sim::SimulationConfig c;
  c.scenario = scenario;
  c.route = route;
  c.frames = frames;
  return c;
}

// Of the poses of `b`, the fraction within `radius` of some pose of `a` (positions).
double fraction_near(const std::vector<Eigen::Isometry3d>& a, const std::vector<Eigen::Isometry3d>& b, double radius) {
  size_t near = 0;
  for (const auto& q : b) {
    for (const auto& p : a) {
      if ((p.translation() - q.translation()).norm() < radius) {
        ++near;
        break;
      }
    }
  }
  return static_cast<double>(near) / b.size();
}

TEST(SimRoutes, EveryRouteSeesTheSameStaticWorld) {
  // Rays from random places in the grid hit the same surfaces in the worlds of all routes (parked
  // cars excepted in the city: they come and go per route).
  for (const char* scenario : {"small", "city"}) {
    const sim::Simulator r0(route_config(scenario, 0, 2));
    const float extent = std::string(scenario) == "small" ? 40.f : 500.f;
    for (int route = 1; route < sim::num_routes(scenario); ++route) {
      const sim::Simulator rk(route_config(scenario, route, 2));
      std::mt19937 rng(7);
      std::uniform_real_distribution<float> u(0.f, 1.f);
      int hits = 0;
      for (int i = 0; i < 2000; ++i) {
        const Eigen::Vector3f o(extent * u(rng), extent * u(rng), r0.world().ground_height(0, 0) + 1.8f);
        const Eigen::Vector3f d = Eigen::Vector3f(u(rng) - 0.5f, u(rng) - 0.5f, 0.3f * (u(rng) - 0.7f)).normalized();
        sim::Hit a, b;
        const bool ha = r0.world().raycast(o, d, 100.f, a), hb = rk.world().raycast(o, d, 100.f, b);
        if (a.label == sim::kCar || b.label == sim::kCar) continue;
        ASSERT_EQ(ha, hb) << scenario << " route " << route << " ray " << i;
        if (!ha) continue;
        EXPECT_EQ(a.range, b.range) << scenario << " route " << route << " ray " << i;
        EXPECT_EQ(a.label, b.label);
        ++hits;
      }
      EXPECT_GT(hits, 1000) << scenario;
    }
  }
}

TEST(SimRoutes, RoutesStartElsewhereOverlapInPartAndDrawTheirOwnTraffic) {
  const sim::Simulator c0(route_config("city", 0, 0));
  for (int route = 1; route < 3; ++route) {
    const sim::Simulator ck(route_config("city", route, 0));
    EXPECT_GT((ck.poses().front().translation() - c0.poses().front().translation()).norm(), 100.0) << route;
    const double shared = fraction_near(c0.poses(), ck.poses(), 5.0);
    EXPECT_GT(shared, 0.2) << route;
    EXPECT_LT(shared, 0.8) << route;
    ASSERT_EQ(ck.traffic().size(), c0.traffic().size());
    EXPECT_NE(ck.traffic().mover(0).s0, c0.traffic().mover(0).s0);
  }
  const sim::Simulator s0(route_config("small", 0, 0)), s2(route_config("small", 2, 0));
  const double shared = fraction_near(s0.poses(), s2.poses(), 5.0);
  EXPECT_GT(shared, 0.1);
  EXPECT_LT(shared, 0.6);
  // The small block's loop from 20 m further on: the same places, other scans.
  const sim::Simulator s1(route_config("small", 1, 0));
  EXPECT_NEAR((s1.poses().front().translation() - s0.poses().front().translation()).norm(), 20.0, 0.5);
  EXPECT_GT(fraction_near(s0.poses(), s1.poses(), 1.0), 0.9);
}

TEST(SimRoutes, PosesWorldMovedToTheFirstPoseArePoses) {
  for (int route : {0, 1}) {
    test::TempDir dir;
    sim::write_simulation(dir.path.string(), route_config("small", route, 4));
    const Trajectory rel = read_trajectory(dir / "poses.txt"), world = read_trajectory(dir / "poses_world.txt");
    ASSERT_EQ(rel.size(), 4u);
    ASSERT_EQ(world.size(), 4u);
    const sim::Simulator s(route_config("small", route, 4));
    for (size_t k = 0; k < 4; ++k) {
      EXPECT_LT(test::translation_error(world.poses[0].inverse() * world.poses[k], rel.poses[k]), 1e-5) << k;
      EXPECT_LT(test::rotation_error_deg(world.poses[0].inverse() * world.poses[k], rel.poses[k]), 1e-4) << k;
      EXPECT_LT(test::translation_error(world.poses[k], s.poses()[k]), 1e-5) << k;
    }
  }
}

TEST(SimRoutes, AnUnknownRouteIsAnErrorNamingTheOption) {
  for (auto [scenario, route] : {std::pair{"corridor", 1}, {"small", 3}, {"loop", 2}, {"city", -1}}) {
    try {
      sim::make_scenario(scenario, 0, route);
      ADD_FAILURE() << scenario << " " << route;
    } catch (const Error& e) { EXPECT_NE(std::string(e.what()).find("--route"), std::string::npos) << e.what(); }
  }
  EXPECT_EQ(sim::make_scenario("loop", 0, 1).waypoints.front(), sim::make_scenario("loop", 0, 0).waypoints[2]);
}

}  // namespace
}  // namespace gcmap
