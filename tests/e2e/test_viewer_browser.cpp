// view.html in a real browser: headless Chromium (Debian's chromium-headless-shell or chromium)
// loads the page from disk; it must log nothing but its own report, report the decimated point
// count, and draw a canvas that is not blank. Skips where no Chromium is installed.
#include <png.h>

#include <cstdlib>
#include <filesystem>
#include <regex>
#include <sstream>
#include <unistd.h>

#include "gcmap/io/file.hpp"
#include "gcmap/viz/view_html.hpp"
#include "test_util.hpp"

namespace gcmap::viz {
namespace {

namespace fs = std::filesystem;

// The first of Debian's Chromium binaries on PATH, or "" when none is installed.
std::string find_chromium() {
  const char* path = std::getenv("PATH");
  std::stringstream dirs(path ? path : "");
  std::vector<std::string> folders;
  for (std::string d; std::getline(dirs, d, ':');) folders.push_back(d);
  for (const char* name : {"chromium-headless-shell", "chromium"})
    for (const std::string& d : folders) {
      const fs::path p = fs::path(d) / name;
      std::error_code ec;
      if (fs::is_regular_file(p, ec) && access(p.c_str(), X_OK) == 0) return p.string();
    }
  return "";
}

// Runs Chromium headless on `page` (bounded by `timeout 60`); stdout and stderr go to files in
// `dir`. Software WebGL (SwiftShader) stands in for a GPU; root needs --no-sandbox.
int run_chromium(const std::string& chromium, const test::TempDir& dir, const std::string& page, const std::string& action,
                 const std::string& name) {
  const std::string cmd = "timeout 60 '" + chromium + "' --headless --no-sandbox --disable-gpu --use-angle=swiftshader" +
                          " --enable-unsafe-swiftshader --enable-logging=stderr --v=0 --no-first-run" + " --user-data-dir='" +
                          dir / "profile" + "' --window-size=800,600 " + action + " 'file://" + page + "' > '" +
                          dir / (name + ".out") + "' 2> '" + dir / (name + ".log") + "'";
  return std::system(cmd.c_str());
}

// The page's console lines, less the GPU process's own performance notes ("GL Driver Message").
std::vector<std::string> console_lines(const std::string& log) {
  std::vector<std::string> lines;
  std::stringstream in(log);
  for (std::string line; std::getline(in, line);)
    if (line.find(":CONSOLE") != std::string::npos && line.find("GL Driver Message") == std::string::npos) lines.push_back(line);
  return lines;
}

struct Rgb8Image {
  int width = 0, height = 0;
  std::vector<uint8_t> rgb;
};

Rgb8Image read_png_rgb(const std::string& path) {
  png_image image{};
  image.version = PNG_IMAGE_VERSION;
  Rgb8Image out;
  if (!png_image_begin_read_from_file(&image, path.c_str())) return out;
  image.format = PNG_FORMAT_RGB;
  std::vector<uint8_t> rgb(PNG_IMAGE_SIZE(image));
  if (!png_image_finish_read(&image, nullptr, rgb.data(), 0, nullptr)) return out;
  out.width = static_cast<int>(image.width), out.height = static_cast<int>(image.height);
  out.rgb = std::move(rgb);
  return out;
}

// Variance of the grey level over columns [x0, width): the right part, clear of the layer panel
// (top left), so the HTML text cannot stand in for a drawn canvas.
double grey_variance(const Rgb8Image& im, int x0) {
  double sum = 0.0, sum2 = 0.0, n = 0.0;
  for (int y = 0; y < im.height; ++y)
    for (int x = x0; x < im.width; ++x) {
      const uint8_t* p = &im.rgb[3 * (static_cast<size_t>(y) * im.width + x)];
      const double g = (p[0] + p[1] + p[2]) / 3.0;
      sum += g, sum2 += g * g, n += 1.0;
    }
  return n > 0 ? sum2 / n - (sum / n) * (sum / n) : 0.0;
}

// A sloped 40 m x 20 m ground with a pole, a straight trajectory over it and two submaps.
RunData synthetic_run() {
  RunData run;
  for (int i = 0; i <= 80; ++i)
    for (int j = 0; j <= 40; ++j) run.map.points.emplace_back(0.5f * i, 10.0f + 0.5f * j, 0.05f * i);
  for (int k = 0; k < 30; ++k) run.map.points.emplace_back(38.0f, -10.0f, 0.1f * k);
  for (int f = 0; f <= 30; ++f) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.translation() << 5.0 + f, 20.0, 1.5;
    run.trajectory.push_back(T);
  }
  for (int s = 0; s < 2; ++s) run.graph.nodes.push_back({s, 15 * s, run.trajectory[15 * s]});
  run.graph.edges.push_back({FactorKind::matching_cost, 1, 0, 1.0});
  return run;
}

TEST(ViewerBrowser, ChromiumLoadsThePageReportsThePointsAndDrawsTheMap) {
  const std::string chromium = find_chromium();
  if (chromium.empty()) GTEST_SKIP() << "no chromium-headless-shell or chromium on PATH (scripts/setup.sh installs it)";
  if (!fs::exists(default_three_dir() + "/build/three.min.js")) GTEST_SKIP() << "Debian's libjs-three is absent";
  test::TempDir dir;
  ViewOptions options;
  options.max_points = 2000;
  const ViewSummary summary = write_view_html(synthetic_run(), dir / "view.html", options);
  ASSERT_EQ(summary.points_written, 2000u);  // decimated from 81 * 41 + 30

  ASSERT_EQ(run_chromium(chromium, dir, dir / "view.html", "--dump-dom", "dom"), 0) << read_file(dir / "dom.log");
  const std::string dom = read_file(dir / "dom.out"), log = read_file(dir / "dom.log");
  std::smatch m;
  ASSERT_TRUE(std::regex_search(dom, m, std::regex("<title>gcmap view: ([0-9]+) points</title>"))) << dom.substr(0, 400);
  EXPECT_EQ(std::stoul(m[1]), summary.points_written);
  EXPECT_NE(dom.find("2000 of 3351 map points loaded"), std::string::npos);
  const std::vector<std::string> console = console_lines(log);
  ASSERT_EQ(console.size(), 1u) << log;  // only the page's own report: no error, warning or exception
  EXPECT_NE(console[0].find("gcmap view: loaded 2000 points"), std::string::npos) << console[0];

  const std::string shot = dir / "shot.png";
  ASSERT_EQ(run_chromium(chromium, dir, dir / "view.html", "--screenshot='" + shot + "'", "shot"), 0)
      << read_file(dir / "shot.log");
  const Rgb8Image image = read_png_rgb(shot);
  ASSERT_EQ(image.width, 800) << shot;
  ASSERT_EQ(image.height, 600) << shot;
  EXPECT_GT(grey_variance(image, 400), 20.0);  // a blank canvas is the uniform background: 0
}

}  // namespace
}  // namespace gcmap::viz
