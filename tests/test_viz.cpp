// Pictures of a run (viz/): a tiny synthetic output folder with known poses, rendered and checked
// pixel by pixel, plus the plots, the viewer page and the error paths.
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <set>

#include "gcmap/core/error.hpp"
#include "gcmap/io/file.hpp"
#include "gcmap/io/json.hpp"
#include "gcmap/io/point_cloud_io.hpp"
#include "gcmap/io/trajectory_io.hpp"
#include "gcmap/viz/chart.hpp"
#include "gcmap/viz/plots.hpp"
#include "gcmap/viz/render.hpp"
#include "gcmap/viz/run_pictures.hpp"
#include "gcmap/viz/view_html.hpp"
#include "test_util.hpp"

namespace gcmap::viz {
namespace {

namespace fs = std::filesystem;
using Kinds = std::vector<FactorKind>;

// Ground at y in [10, 30] and a pole at (38, -10); the trajectory runs along y = 20 from x = 5 to
// 35; three submaps start at frames 0, 10 and 20. graph.json is written in a world frame offset
// from the output frame, as `gcmap map` does.
struct SyntheticRun {
  test::TempDir dir;
  Poses trajectory;
  const Eigen::Isometry3d T_world_out = Eigen::Translation3d(100, -50, 3) * Eigen::AngleAxisd(0.7, Eigen::Vector3d::UnitZ());

  explicit SyntheticRun(const Kinds& kinds = {FactorKind::matching_cost, FactorKind::loop}, bool empty_map = false) {
    PointCloud map;
    for (int i = 0; i <= 80 && !empty_map; ++i)
      for (int j = 0; j <= 40; ++j) {
        map.points.emplace_back(0.5f * i, 10.0f + 0.5f * j, 0.01f * i);
        map.intensities.push_back(static_cast<float>(i));
      }
    for (int k = 0; k < 30 && !empty_map; ++k) {
      map.points.emplace_back(38.0f, -10.0f, 0.1f * k);
      map.intensities.push_back(1.0f);
    }
    write_ply(dir / "map.ply", map);
    Trajectory t;
    for (int f = 0; f <= 30; ++f) {
      Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
      T.translation() << 5.0 + f, 20.0, 1.5;
      t.poses.push_back(T);
    }
    trajectory = t.poses;
    write_trajectory(dir / "trajectory.kitti", t);
    write_trajectory(dir / "odometry.kitti", t);
    write_graph(kinds);
    write_stats();
  }

  void write_graph(const Kinds& kinds) const {
    Json submaps = Json::array(), factors = Json::array();
    for (int s = 0; s < 3; ++s) {
      double v[7];
      pose_to_xyz_quat(T_world_out * trajectory[10 * s], v);
      Json j = Json::object();
      j["id"] = s;
      j["pose"] = Json::Array(v, v + 7);
      j["first_frame"] = 10 * s;
      submaps.push_back(j);
    }
    for (size_t i = 0; i < kinds.size(); ++i) {
      Json j = Json::object();
      j["type"] = to_string(kinds[i]);
      j["source"] = kinds[i] == FactorKind::loop ? 2 : static_cast<int>(i % 2) + 1;
      j["target"] = kinds[i] == FactorKind::loop ? 0 : static_cast<int>(i % 2);
      if (kinds[i] != FactorKind::matching_cost) j["final_weight"] = 0.5;
      factors.push_back(j);
    }
    Json g = Json::object();
    g["submaps"] = submaps;
    g["factors"] = factors;
    write(dir / "graph.json", g.dump());
  }

  void write_stats() const {
    Json t = Json::object(), m = Json::object(), per = Json::array();
    m["mean_ms"] = 12.5, m["std_ms"] = 2.0, m["max_ms"] = 20.0, m["count"] = 31;
    t["odometry"] = m;
    for (int s = 1; s <= 3; ++s) {
      Json p = Json::object();
      p["submaps"] = s, p["factors"] = s * (s - 1) / 2, p["global_optimization_ms"] = 3.0 * s, p["global_iterations"] = 2;
      per.push_back(p);
    }
    Json stats = Json::object();
    stats["timing"] = t;
    stats["per_submap"] = per;
    write(dir / "stats.json", stats.dump());
  }

  static void write(const std::string& path, const std::string& text) {
    write_file_atomic(path, [&](std::ostream& o) { o << text; });
  }
  RunData read(bool graph = true) const { return read_run(dir.path.string(), graph); }
};

Rgb pixel_at(const MapPicture& pic, const Eigen::Vector3d& world) {
  const Eigen::Vector2d p = pic.view.pixel(world);
  return pic.image.at(static_cast<int>(p.x()), static_cast<int>(p.y()));
}

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& e) { return e.what(); }
  return "(no error)";
}

RenderOptions small(ColorMode color = ColorMode::height) {
  RenderOptions o;
  o.size = 400;
  o.color = color;
  return o;
}

TEST(Viz, GraphNodesAreExpressedInTheTrajectoryFrame) {
  SyntheticRun s;
  const RunData run = s.read();
  ASSERT_EQ(run.graph.nodes.size(), 3u);
  for (const GraphNode& n : run.graph.nodes)
    EXPECT_LT((n.T_out_submap.translation() - s.trajectory[n.first_frame].translation()).norm(), 1e-6) << n.id;
  EXPECT_EQ(run.graph.edges.back().kind, FactorKind::loop);
  EXPECT_DOUBLE_EQ(run.graph.edges.back().weight, 0.5);
}

TEST(Viz, TrajectoryNodesMapAndBackgroundPixels) {
  SyntheticRun s;
  const RunData run = s.read();
  for (ColorMode mode : {ColorMode::height, ColorMode::intensity, ColorMode::submap}) {
    const MapPicture pic = render_map(run, small(mode));
    for (int f : {3, 8, 13, 27}) EXPECT_EQ(pixel_at(pic, s.trajectory[f].translation()), palette::trajectory) << f;
    for (const GraphNode& n : run.graph.nodes) EXPECT_EQ(pixel_at(pic, n.T_out_submap.translation()), palette::node) << n.id;
    EXPECT_EQ(pixel_at(pic, {15, 0, 0}), palette::background);  // 10 m from any point
    const Rgb ground = pixel_at(pic, {20, 26, 0});
    EXPECT_NE(ground, palette::background);
    EXPECT_NE(ground, palette::trajectory);
    EXPECT_TRUE(pic.note.empty());
  }
}

TEST(Viz, SameInputGivesTheSameBytes) {
  SyntheticRun s;
  test::TempDir out;
  render_run(s.dir.path.string(), out / "a.png", small());
  render_run(s.dir.path.string(), out / "b.png", small());
  const std::string a = read_file(out / "a.png");
  EXPECT_EQ(a.substr(0, 4), "\x89PNG");
  EXPECT_EQ(a, read_file(out / "b.png"));
  EXPECT_EQ(a, encode_png(render_map(s.read(), small()).image));
}

TEST(Viz, LegendListsExactlyTheFactorKindsPresent) {
  for (const Kinds& kinds : {Kinds{FactorKind::matching_cost, FactorKind::loop}, Kinds{FactorKind::odometry, FactorKind::se3},
                             Kinds{FactorKind::matching_cost, FactorKind::matching_cost, FactorKind::odometry}, Kinds{}}) {
    SyntheticRun s(kinds);
    const RunData run = s.read();
    std::set<FactorKind> listed;
    for (const LegendEntry& e : render_map(run, small()).legend)
      if (e.factor) EXPECT_TRUE(listed.insert(*e.factor).second) << e.label;
    EXPECT_EQ(listed, std::set<FactorKind>(kinds.begin(), kinds.end()));
    RenderOptions no_graph = small();
    no_graph.graph = false;
    const auto entries = legend_entries(run, no_graph);
    ASSERT_EQ(entries.size(), 1u);
    EXPECT_EQ(entries[0].label, "trajectory (31 frames)");
  }
}

TEST(Viz, EmptyMapRendersAPictureThatSaysSo) {
  SyntheticRun s({}, true);
  const MapPicture pic = render_map(s.read(), small());
  EXPECT_NE(pic.note.find("empty map"), std::string::npos);
  EXPECT_EQ(pixel_at(pic, s.trajectory[3].translation()), palette::trajectory);
}

TEST(Viz, ErrorsNameTheFile) {
  SyntheticRun s;
  const std::string dir = s.dir.path.string();
  EXPECT_NE(error_of([] { read_run("/nonexistent/gcmap_run", true); }).find("/nonexistent/gcmap_run"), std::string::npos);
  RenderOptions bad = small();
  bad.size = 10;
  EXPECT_NE(error_of([&] { render_map(s.read(), bad); }).find("size"), std::string::npos);
  for (const char* text : {"{\"submaps\": [{\"id\": 0", "", "[1, 2]",
                           "{\"submaps\": [], \"factors\": [{\"type\": \"odometry\", \"source\": 1, \"target\": 0}]}",
                           "{\"submaps\": [], \"factors\": [{\"type\": \"spring\", \"source\": 0, \"target\": 0}]}"}) {
    SyntheticRun::write(s.dir / "graph.json", text);
    EXPECT_NE(error_of([&] { s.read(); }).find(s.dir / "graph.json"), std::string::npos) << text;
  }
  EXPECT_NO_THROW(s.read(false));  // --no-graph does not need graph.json
  SyntheticRun::write(s.dir / "stats.json", "{\"timing\": {\"odometry\": {\"mean_ms\": 1");
  EXPECT_NE(error_of([&] { read_stats_json(s.dir / "stats.json"); }).find(s.dir / "stats.json"), std::string::npos);
  fs::remove(s.dir / "map.ply");
  EXPECT_NE(error_of([&] { s.read(); }).find(s.dir / "map.ply"), std::string::npos);
  SyntheticRun::write(s.dir / "map.ply", "ply\nformat binary_little_endian 1.0\nelement vertex 100\nproperty float x\n");
  EXPECT_NE(error_of([&] { s.read(); }).find(s.dir / "map.ply"), std::string::npos);
}

TEST(Viz, ViewPageInlinesThreeJsAndHoldsTheLayers) {
  const std::string three = default_three_dir() + "/build/three.min.js";
  if (!fs::exists(three)) GTEST_SKIP() << three << " is absent (Debian's libjs-three)";
  SyntheticRun s;
  test::TempDir out;
  ViewOptions o;
  o.max_points = 1000;
  const ViewSummary v = write_view_html(s.read(), out / "view.html", o);
  EXPECT_EQ(v.map_points, 81u * 41u + 30u);
  EXPECT_EQ(v.points_written, 1000u);
  const std::string page = read_file(out / "view.html");
  EXPECT_EQ(v.bytes, page.size());
  const std::string lib = read_file(three), orbit = read_file(default_three_dir() + "/examples/js/controls/OrbitControls.js");
  EXPECT_NE(page.find(lib.substr(lib.size() / 2, 300)), std::string::npos);
  EXPECT_NE(page.find(orbit.substr(orbit.size() / 2, 300)), std::string::npos);
  for (const char* layer :
       {"\"trajectory\":[5,20,1.5,6,20,1.5", "\"nodes\":[", "matching-cost factors", "explicit loops", "addLayer('map"})
    EXPECT_NE(page.find(layer), std::string::npos) << layer;
  const std::string open = "<script id=\"gcmap-points\" type=\"text/plain\">";
  const size_t a = page.find(open) + open.size(), b = page.find("</script>", a);
  EXPECT_EQ(b - a, 1000u * 6 / 3 * 4);  // base64 of 6 bytes per point
  o.three_dir = "/nonexistent/three";
  const std::string e = error_of([&] { write_view_html(s.read(), out / "v2.html", o); });
  EXPECT_NE(e.find("/nonexistent/three/build/three.min.js"), std::string::npos) << e;
  EXPECT_NE(e.find("libjs-three"), std::string::npos) << e;
}

TEST(Viz, PlotsWithAndWithoutGroundTruth) {
  SyntheticRun s;
  test::TempDir out;
  PlotOptions o;
  EXPECT_EQ(write_plots(s.dir.path.string(), out / "a", o).size(), 2u);
  o.ground_truth = s.dir / "trajectory.kitti";
  o.format = FigureFormat::svg;
  const auto written = write_plots(s.dir.path.string(), out / "b", o);
  ASSERT_EQ(written.size(), 4u);
  for (const WrittenFile& f : written) EXPECT_NE(read_file(f.path).find("<svg"), std::string::npos) << f.path;
  Trajectory short_gt;
  short_gt.poses.assign(5, Eigen::Isometry3d::Identity());
  write_trajectory(out / "gt.kitti", short_gt);
  o.ground_truth = out / "gt.kitti";
  EXPECT_NE(error_of([&] { write_plots(s.dir.path.string(), out / "c", o); }).find("trajectory.kitti"), std::string::npos);
  fs::remove(s.dir / "stats.json");
  EXPECT_NE(error_of([&] { write_plots(s.dir.path.string(), out / "c", {}); }).find("stats.json"), std::string::npos);
}

TEST(Viz, RunPicturesAndCommandsSayWhatTheyWrote) {
  SyntheticRun s;
  RunPicturesOptions o;
  o.render.size = 300;
  o.plots = true;
  const auto written = write_run_pictures(s.dir.path.string(), o);
  ASSERT_EQ(written.size(), 3u);
  EXPECT_EQ(written[0].path, s.dir / "map.png");
  for (const WrittenFile& f : written) EXPECT_TRUE(fs::exists(f.path)) << f.path;
  test::TempDir tmp;
  const std::string cmd =
      std::string(GCMAP_CLI) + " render " + s.dir.path.string() + " --size 300 -o " + (tmp / "m.png") + " >" + (tmp / "out");
  ASSERT_EQ(std::system(cmd.c_str()), 0);
  EXPECT_NE(read_file(tmp / "out").find("wrote " + (tmp / "m.png")), std::string::npos);
  const std::string bad = std::string(GCMAP_CLI) + " render /nonexistent/run 2>" + (tmp / "err");
  EXPECT_EQ(WEXITSTATUS(std::system(bad.c_str())), 2);
  EXPECT_NE(read_file(tmp / "err").find("/nonexistent/run"), std::string::npos);
}

TEST(Viz, NiceTicks) {
  EXPECT_EQ(nice_ticks(0.0, 7.3), (std::vector<double>{0, 2, 4, 6}));
  EXPECT_EQ(nice_ticks(50.0, 850.0), (std::vector<double>{200, 400, 600, 800}));
}

}  // namespace
}  // namespace gcmap::viz
