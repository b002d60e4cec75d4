#include <iostream>

#include "commands.hpp"
#include "gcmap/core/error.hpp"
#include "gcmap/viz/plots.hpp"

namespace gcmap::cli {

void add_plot(CLI::App& app, Runner& run) {
  struct Options {
    std::string dir, output, gt, calib, format = "png";
  };
  auto opt = std::make_shared<Options>();
  auto* cmd =
      app.add_subcommand("plot", "The paper's figures from a run: Fig. 10, per-module timings, accuracy against ground truth");
  cmd->add_option("out", opt->dir, "Output folder of gcmap map (stats.json, trajectory.kitti, odometry.kitti)")->required();
  cmd->add_option("-o,--output", opt->output, "Folder for the figures")->required();
  cmd->add_option("--gt", opt->gt,
                  "Ground-truth poses (KITTI or TUM, one per frame): adds the trajectory and KITTI error figures");
  cmd->add_option("--calib", opt->calib,
                  "With --gt: KITTI calib.txt (ground truth in camera 0, estimates in the Velodyne frame)");
  cmd->add_option("--format", opt->format, "png or svg")->check(CLI::IsMember({"png", "svg"}))->capture_default_str();
  cmd->footer("Writes global_optimization, timings and with --gt trajectory and kitti_errors (.png or .svg).");
  cmd->callback([opt, &run] {
    run = [opt] {
      if (!opt->calib.empty() && opt->gt.empty()) throw Error("--calib needs --gt");
      viz::PlotOptions po;
      po.format = viz::parse_figure_format(opt->format);
      po.ground_truth = opt->gt;
      po.calib = opt->calib;
      for (const viz::WrittenFile& f : viz::write_plots(opt->dir, opt->output, po))
        std::cout << "wrote " << f.path << ": " << f.what << "\n";
      return 0;
    };
  });
}

}  // namespace gcmap::cli
