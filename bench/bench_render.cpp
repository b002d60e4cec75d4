// Top-down render of a large map (issue target: 10 M points under 2 s on 2 cores): N random points
// over 800 x 600 m written as map.ply, then the PLY read, the picture and the PNG timed apart, the
// same work as `gcmap render DIR --no-graph`. Not a test.
// Usage: bench_render [MILLIONS_OF_POINTS=10] [DIR] (default DIR: the system temp folder).
#include <tbb/info.h>

#include <cstdio>
#include <filesystem>
#include <random>
#include <string>

#include "gcmap/core/timer.hpp"
#include "gcmap/io/point_cloud_io.hpp"
#include "gcmap/io/trajectory_io.hpp"
#include "gcmap/viz/image.hpp"
#include "gcmap/viz/render.hpp"

using namespace gcmap;
namespace fs = std::filesystem;

int main(int argc, char** argv) {
  const double millions = argc > 1 ? std::stod(argv[1]) : 10.0;
  const fs::path dir = fs::path(argc > 2 ? argv[2] : fs::temp_directory_path().string()) / "gcmap_bench_render";
  fs::create_directories(dir);
  viz::RunData run;
  std::mt19937 rng(1);
  std::uniform_real_distribution<float> ux(0, 800), uy(0, 600), uz(-2, 20);
  run.map.points.resize(static_cast<size_t>(millions * 1e6));
  for (auto& p : run.map.points) p = Eigen::Vector3f(ux(rng), uy(rng), uz(rng));
  for (int k = 0; k < 100; ++k) run.trajectory.push_back(Eigen::Isometry3d(Eigen::Translation3d(8.0 * k, 6.0 * k, 0)));
  write_ply((dir / "map.ply").string(), run.map);
  std::printf("%zu points, %d threads, map.ply %.0f MB\n", run.map.size(), tbb::info::default_concurrency(),
              fs::file_size(dir / "map.ply") / 1e6);
  for (int rep = 0; rep < 3; ++rep) {
    Stopwatch total, w;
    run.map = read_point_cloud((dir / "map.ply").string());
    const double read_ms = w.lap_ms();
    viz::RenderOptions options;
    options.graph = false;
    const viz::MapPicture pic = viz::render_map(run, options);
    const double render_ms = w.lap_ms();
    viz::write_png((dir / "map.png").string(), pic.image);
    const double png_ms = w.ms();
    std::printf("read %.0f ms (%.0f M points/s)  picture %.0f ms  png %.0f ms  total %.2f s\n", read_ms,
                run.map.size() / read_ms / 1e3, render_ms, png_ms, total.ms() / 1e3);
  }
  fs::remove_all(dir);
}
