#include <iostream>

#include "commands.hpp"
#include "gcmap/core/timer.hpp"
#include "gcmap/sim/simulator.hpp"

namespace gcmap::cli {

void add_simulate(CLI::App& app, Runner& run) {
  auto opt = std::make_shared<sim::SimulationConfig>();
  auto out = std::make_shared<std::string>();
  auto* cmd = app.add_subcommand("simulate", "Generate a synthetic LiDAR sequence with exact ground truth (KITTI layout)");
  cmd->add_option("-o,--output", *out, "Output folder")->required();
  cmd->add_option("--scenario", opt->scenario, "loop, small or corridor")->capture_default_str();
  cmd->add_option("--frames", opt->frames, "Number of frames (0 = the scenario's default)")->capture_default_str();
  cmd->add_option("--seed", opt->seed, "World and noise seed")->capture_default_str();
  cmd->add_option("--sensor", opt->sensor, "hdl64, vlp16 or os1-64")->capture_default_str();
  cmd->add_option("--noise", opt->noise, "Range noise sigma in m")->capture_default_str();
  cmd->callback([opt, out, &run] {
    run = [opt, out] {
      Stopwatch w;
      const size_t points = sim::write_simulation(*out, *opt, false);
      std::cout << "{\"output\":\"" << *out << "\",\"points\":" << points << ",\"seconds\":" << w.ms() / 1000.0 << "}\n";
      return 0;
    };
  });
}

}  // namespace gcmap::cli
