#include <filesystem>
#include <iostream>

#include "commands.hpp"
#include "gcmap/viz/view_html.hpp"

namespace gcmap::cli {

void add_view(CLI::App& app, Runner& run) {
  struct Options {
    std::string dir, output;
    viz::ViewOptions view;
  };
  auto opt = std::make_shared<Options>();
  auto* cmd =
      app.add_subcommand("view", "Write OUT/view.html: a 3D viewer of the map, trajectory and factor graph for any browser");
  cmd->add_option("out", opt->dir, "Output folder of gcmap map (map.ply, trajectory.kitti, graph.json)")->required();
  cmd->add_option("-o,--output", opt->output, "Page to write (default: OUT/view.html)");
  cmd->add_option("--max-points", opt->view.max_points, "The map is evenly decimated to at most this many points")
      ->check(CLI::Range(size_t{1}, size_t{50'000'000}))
      ->capture_default_str();
  cmd->add_option("--three-dir", opt->view.three_dir, "Folder of three.js (Debian's libjs-three)")->capture_default_str();
  cmd->callback([opt, &run] {
    run = [opt] {
      const std::string path = opt->output.empty() ? (std::filesystem::path(opt->dir) / "view.html").string() : opt->output;
      const viz::WrittenFile f = viz::view_run(opt->dir, path, opt->view);
      std::cout << "wrote " << f.path << ": " << f.what << "; open it in a browser (no server needed)\n";
      return 0;
    };
  });
}

}  // namespace gcmap::cli
