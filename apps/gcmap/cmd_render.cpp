#include <filesystem>
#include <iostream>

#include "commands.hpp"
#include "gcmap/core/timer.hpp"
#include "gcmap/viz/render.hpp"

namespace gcmap::cli {

void add_render(CLI::App& app, Runner& run) {
  struct Options {
    std::string dir, output, color = "height";
    int size = 2000;
    bool no_graph = false;
  };
  auto opt = std::make_shared<Options>();
  auto* cmd = app.add_subcommand("render", "Top-down PNG of a run: map, trajectory, factor graph, scale bar, legend");
  cmd->add_option("out", opt->dir, "Output folder of gcmap map (map.ply, trajectory.kitti, graph.json)")->required();
  cmd->add_option("-o,--output", opt->output, "PNG to write (default: OUT/map.png)");
  cmd->add_option("--color", opt->color, "Map colours: height, intensity or submap")
      ->check(CLI::IsMember({"height", "intensity", "submap"}))
      ->capture_default_str();
  cmd->add_option("--size", opt->size, "Pixels along the longer side")->check(CLI::Range(200, 16384))->capture_default_str();
  cmd->add_flag("--no-graph", opt->no_graph, "Leave out the submap nodes and factors");
  cmd->callback([opt, &run] {
    run = [opt] {
      viz::RenderOptions ro;
      ro.color = viz::parse_color_mode(opt->color);
      ro.size = opt->size;
      ro.graph = !opt->no_graph;
      const std::string png = opt->output.empty() ? (std::filesystem::path(opt->dir) / "map.png").string() : opt->output;
      Stopwatch w;
      const viz::WrittenFile f = viz::render_run(opt->dir, png, ro);
      std::cout << "wrote " << f.path << ": " << f.what << " in " << w.ms() / 1000.0 << " s\n";
      return 0;
    };
  });
}

}  // namespace gcmap::cli
