// Occupancy grids: the map_server files round trip, and rays on hand-made scenes give the cells
// that geometry says (walls hit, the space before them free, what lies behind them unknown).
#include <cmath>
#include <fstream>
#include <regex>

#include "gcmap/core/error.hpp"
#include "gcmap/io/occupancy_grid_io.hpp"
#include "gcmap/mapping/occupancy_grid.hpp"
#include "test_util.hpp"

namespace gcmap {
namespace {

OccupancyGrid three_by_two() {
  OccupancyGrid g;
  g.width = 3;
  g.height = 2;
  g.resolution = 0.1;
  g.origin = {-1.5, 2.25};
  g.cells = {Occupancy::occupied, Occupancy::free, Occupancy::unknown,  // row 0: the lowest y
             Occupancy::free,     Occupancy::free, Occupancy::occupied};
  return g;
}

TEST(OccupancyGridIo, MapServerFilesRoundTripWithItsConventions) {
  test::TempDir tmp;
  write_map_server(tmp.path.string(), "map", three_by_two());
  const std::string yaml = test::slurp(tmp / "map.yaml");
  for (const char* line :
       {"image: map.pgm\n", "mode: trinary\n", "resolution: 0.100000\n", "origin: [-1.500000, 2.250000, 0.0]\n", "negate: 0\n",
        "occupied_thresh: 0.65\n", "free_thresh: 0.196\n"})
    EXPECT_NE(yaml.find(line), std::string::npos) << line << " in\n" << yaml;
  const std::string pgm = test::slurp(tmp / "map.pgm");
  ASSERT_EQ(pgm.substr(0, 3), "P5\n");
  // The image's top row is the grid's highest row; occupied 0, free 254, unknown 205.
  const std::string pixels = pgm.substr(pgm.size() - 6);
  EXPECT_EQ(pixels, std::string("\xfe\xfe\x00\x00\xfe\xcd", 6));
  const OccupancyGrid back = read_map_server(tmp / "map.yaml");
  EXPECT_EQ(back.width, 3);
  EXPECT_EQ(back.height, 2);
  EXPECT_DOUBLE_EQ(back.resolution, 0.1);
  EXPECT_EQ(back.origin, Eigen::Vector2d(-1.5, 2.25));
  EXPECT_EQ(back.cells, three_by_two().cells);
  int cx, cy;
  ASSERT_TRUE(back.cell_of(-1.25, 2.39, cx, cy));
  EXPECT_EQ(cx, 2);
  EXPECT_EQ(cy, 1);
  EXPECT_FALSE(back.cell_of(-1.51, 2.3, cx, cy));
}

void expect_error(const std::string& yaml_path, const std::string& message) {
  try {
    read_map_server(yaml_path);
    ADD_FAILURE() << "no error for " << yaml_path;
  } catch (const Error& e) { EXPECT_NE(std::string(e.what()).find(message), std::string::npos) << e.what(); }
}

TEST(OccupancyGridIo, MalformedFilesNameTheFileAndTheProblem) {
  test::TempDir tmp;
  write_map_server(tmp.path.string(), "map", three_by_two());
  const std::string yaml = test::slurp(tmp / "map.yaml");
  std::ofstream(tmp / "scale.yaml") << std::regex_replace(yaml, std::regex("trinary"), "scale");
  expect_error(tmp / "scale.yaml", "scale.yaml: only mode trinary");
  std::ofstream(tmp / "nores.yaml") << std::regex_replace(yaml, std::regex("resolution: [0-9.]+\n"), "");
  expect_error(tmp / "nores.yaml", "nores.yaml: no key 'resolution'");
  const std::string pgm = test::slurp(tmp / "map.pgm");
  std::ofstream(tmp / "map.pgm", std::ios::binary) << pgm.substr(0, pgm.size() - 1);
  expect_error(tmp / "map.yaml", "map.pgm: pixel data of the wrong size");
  expect_error(tmp / "absent.yaml", "absent.yaml: no such file");
}

// A sensor 1.7 m above flat ground at z = 0, in the middle of a 12 m disk of ground returns
// (sampled every 0.1 m), with a wall at x = 5 (|y| < 3, 3 m tall) hiding the ground behind it.
struct Scene {
  std::vector<Eigen::Vector3f> ends, origins{{0.f, 0.f, 1.7f}};
  std::vector<uint16_t> origin_of;
  void add(const Eigen::Vector3f& p) {
    ends.push_back(p);
    origin_of.push_back(0);
  }
  RayBatch batch() const { return {ends, origin_of, origins}; }
};

bool behind_wall(float x, float y) { return x >= 5.f && std::abs(y * 5.f / x) < 3.f; }

Scene wall_scene(const Eigen::Vector3f& sensor) {
  Scene s;
  s.origins = {sensor};
  for (float x = -12.f; x <= 12.f; x += 0.1f)
    for (float y = -12.f; y <= 12.f; y += 0.1f)
      if (x * x + y * y < 144.f && !behind_wall(x, y)) s.add({x, y, 0.f});
  for (float y = -2.95f; y < 3.f; y += 0.05f)
    for (float z = 0.05f; z < 3.f; z += 0.1f) s.add({5.01f, y, z});
  return s;
}

OccupancyGrid build(const std::vector<Scene>& scenes, GridOptions o = {}) {
  o.resolution = 0.1;
  OccupancyGridBuilder b(Eigen::AlignedBox2d(Eigen::Vector2d(-20, -20), Eigen::Vector2d(20, 20)), o);
  for (const Scene& s : scenes) b.add_ground(s.batch());
  b.finish_ground();
  for (const Scene& s : scenes) b.add_rays(s.batch());
  return b.grid();
}

// A scene seen by the two scans a cell needs (GridOptions::min_scans).
std::vector<Scene> twice(const Scene& s) { return {s, s}; }

Occupancy at(const OccupancyGrid& g, double x, double y) {
  int cx, cy;
  return g.cell_of(x, y, cx, cy) ? g.at(cx, cy) : Occupancy::unknown;
}

TEST(OccupancyGrid, WallHitSpaceBeforeItFreeBehindItUnknown) {
  const OccupancyGrid g = build(twice(wall_scene({0.f, 0.f, 1.7f})));
  for (float y = -2.5f; y <= 2.5f; y += 0.5f) {
    EXPECT_EQ(at(g, 5.05, y), Occupancy::occupied) << y;
    EXPECT_EQ(at(g, 4.75, y), Occupancy::free) << y;
    EXPECT_EQ(at(g, 7.0, y), Occupancy::unknown) << y;  // no ray went there
  }
  EXPECT_EQ(at(g, -8.0, 3.0), Occupancy::free);  // ground: below the band, passed over
  EXPECT_EQ(at(g, 14.0, 0.0), Occupancy::unknown);
  // Only the wall is occupied: 60 cells along it, a row or two thick.
  EXPECT_GE(g.count(Occupancy::occupied), 55u);
  EXPECT_LE(g.count(Occupancy::occupied), 130u);
}

TEST(OccupancyGrid, HeightIsAboveTheLocalGroundNotTheSensor) {
  // The scene on a slope rising 0.1 m per m along y: 10 m uphill the ground lies 0.7 m below the
  // sensor, 1 m above the sensor's own ground: an obstacle in a band taken from the sensor's height.
  Scene s = wall_scene({0.f, 0.f, 1.7f});
  for (Eigen::Vector3f& p : s.ends) p.z() += 0.1f * p.y();
  const OccupancyGrid g = build(twice(s));
  EXPECT_EQ(at(g, 0.0, 10.0), Occupancy::free);
  EXPECT_EQ(at(g, -3.0, 11.0), Occupancy::free);
  EXPECT_EQ(at(g, 5.05, 2.0), Occupancy::occupied);
  EXPECT_EQ(at(g, 5.05, -2.0), Occupancy::occupied);
  EXPECT_LE(g.count(Occupancy::occupied), 130u);
}

TEST(OccupancyGrid, ReturnsAboveTheBandAreNoObstacles) {
  // Ground all around and a 2 m wide awning at 2.5 m, over the band: the rays pass beneath it.
  Scene s;
  for (float x = -10.f; x <= 10.f; x += 0.1f)
    for (float y = -10.f; y <= 10.f; y += 0.1f) s.add({x, y, 0.f});
  for (float y = -1.f; y < 1.f; y += 0.05f) s.add({8.f, y, 2.5f});
  const OccupancyGrid g = build(twice(s));
  EXPECT_EQ(g.count(Occupancy::occupied), 0u);
  EXPECT_EQ(at(g, 8.05, 0.0), Occupancy::free);
  GridOptions o;
  o.height_max = 3.0f;  // a band that holds it
  EXPECT_EQ(at(build(twice(s), o), 8.05, 0.0), Occupancy::occupied);
}

TEST(OccupancyGrid, SomethingThatMovedAwayIsFree) {
  // Scan 0 sees a car at x = 3; four later scans from the same place see the ground through it.
  Scene first = wall_scene({0.f, 0.f, 1.7f});
  for (float y = -1.f; y <= 1.f; y += 0.05f)
    for (float z = 0.3f; z < 1.5f; z += 0.1f) first.add({3.0f, y, z});
  std::vector<Scene> scenes = twice(first);
  for (int k = 0; k < 8; ++k) scenes.push_back(wall_scene({0.f, 0.f, 1.7f}));
  const OccupancyGrid g = build(scenes);
  EXPECT_EQ(at(g, 3.05, 0.0), Occupancy::free);
  EXPECT_EQ(at(g, 5.05, 0.0), Occupancy::occupied);
  // Seen by these two scans only, the car is occupied (no evidence against it).
  EXPECT_EQ(at(build(twice(first)), 3.05, 0.0), Occupancy::occupied);
}

TEST(OccupancyGrid, AStrayEchoBeyondTheGroundDoesNotSinkIt) {
  // A ray that came back from 1 m below the ground (multipath): the lowest return of its column,
  // but alone. Were it the ground, the street around it would read as 1 m high obstacles.
  Scene s = wall_scene({0.f, 0.f, 1.7f});
  s.add({-6.f, 2.f, -1.f});
  const OccupancyGrid g = build(twice(s));
  for (double x = -7.0; x <= -5.0; x += 0.5)
    for (double y = 1.0; y <= 3.0; y += 0.5) EXPECT_EQ(at(g, x, y), Occupancy::free) << x << ", " << y;
  EXPECT_LE(g.count(Occupancy::occupied), 130u);
}

TEST(OccupancyGrid, OneScansStrayRayThroughAWallIsNoEvidence) {
  // One of the two scans has an echo from 4 m behind the wall, its ray through the wall: the cells
  // behind it stay unknown, neither free nor an obstacle, and the wall stays occupied.
  Scene stray = wall_scene({0.f, 0.f, 1.7f});
  stray.add({9.f, 0.2f, 1.0f});
  const OccupancyGrid g = build({stray, wall_scene({0.f, 0.f, 1.7f})});
  EXPECT_EQ(at(g, 7.05, 0.15), Occupancy::unknown);
  EXPECT_EQ(at(g, 9.05, 0.25), Occupancy::unknown);
  EXPECT_EQ(at(g, 5.05, 0.0), Occupancy::occupied);
  EXPECT_EQ(at(g, 4.75, 0.0), Occupancy::free);
}

TEST(OccupancyGrid, TooFineForTheAreaIsAnErrorNamingTheOption) {
  GridOptions o;
  o.resolution = 0.001;
  try {
    OccupancyGridBuilder b(Eigen::AlignedBox2d(Eigen::Vector2d(0, 0), Eigen::Vector2d(1000, 1000)), o);
    ADD_FAILURE() << "no error";
  } catch (const Error& e) { EXPECT_NE(std::string(e.what()).find("--grid-resolution"), std::string::npos) << e.what(); }
}

}  // namespace
}  // namespace gcmap
