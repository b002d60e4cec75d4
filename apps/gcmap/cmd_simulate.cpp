#include <iostream>

#include "commands.hpp"
#include "gcmap/core/error.hpp"
#include "gcmap/core/timer.hpp"
#include "gcmap/sim/simulator.hpp"

namespace gcmap::cli {

void add_simulate(CLI::App& app, Runner& run) {
  auto opt = std::make_shared<sim::SimulationConfig>();
  auto out = std::make_shared<std::string>();
  auto realism = std::make_shared<std::string>();
  auto ideal = std::make_shared<bool>(false);
  auto* cmd = app.add_subcommand("simulate", "Generate a synthetic LiDAR sequence with exact ground truth (KITTI layout)");
  cmd->add_option("-o,--output", *out, "Output folder")->required();
  cmd->add_option("--scenario", opt->scenario,
                  "loop, small, corridor (ideal by default), city, highway, forest (realistic by default)")
      ->capture_default_str();
  cmd->add_option("--frames", opt->frames,
                  "Number of frames (0 = the scenario's default; city, highway, forest: the first N frames of the drive)")
      ->capture_default_str();
  cmd->add_option("--seed", opt->seed, "World and noise seed")->capture_default_str();
  cmd->add_option("--route", opt->route,
                  "Which route through the seed's world: city and small have 0-2, loop 0-1 (noise and traffic differ per "
                  "route; poses_world.txt gives the poses in the shared world frame)")
      ->capture_default_str();
  cmd->add_option("--sensor", opt->sensor, "hdl64, vlp16, os1-64, os1-128 or avia (Livox-Avia-like rosette)")
      ->capture_default_str();
  cmd->add_option("--noise", opt->noise, "Range noise sigma in m")->capture_default_str();
  cmd->add_flag("--ideal", *ideal, "No realism: scans at one instant, static world, Gaussian range noise only");
  cmd->add_option("--realism", *realism,
                  "all, none, or the keys to enable: motion_distortion, moving_objects, labels, calibration, "
                  "range_noise, dropouts, mixed_pixels, spurious, curbs, vegetation (default: the scenario's)");
  cmd->callback([opt, out, realism, ideal, &run] {
    run = [opt, out, realism, ideal] {
      if (*ideal && !realism->empty()) throw Error("--ideal and --realism: give one of them");
      if (*ideal) opt->realism = sim::RealismConfig::none();
      if (!realism->empty()) opt->realism = sim::parse_realism(*realism);
      Stopwatch w;
      const size_t points = sim::write_simulation(*out, *opt, false);
      std::cout << "{\"output\":\"" << *out << "\",\"points\":" << points << ",\"seconds\":" << w.ms() / 1000.0 << "}\n";
      return 0;
    };
  });
}

}  // namespace gcmap::cli
