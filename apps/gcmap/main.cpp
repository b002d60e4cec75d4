#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>
#include <tbb/global_control.h>

#include <cmath>
#include <csignal>
#include <iostream>
#include <sstream>

#include "commands.hpp"
#include "gcmap/core/error.hpp"
#include "gcmap/core/memory.hpp"
#include "gcmap/core/se3.hpp"

namespace gcmap::cli {

Eigen::Isometry3d parse_pose_option(const std::string& option, const std::string& text) {
  std::istringstream ss(text);
  double v[7];
  for (double& x : v)
    if (!(ss >> x) || !std::isfinite(x)) throw Error(option + ": expected \"x y z qx qy qz qw\", got \"" + text + "\"");
  std::string extra;
  if (ss >> extra) throw Error(option + ": expected 7 numbers, got more: \"" + text + "\"");
  if (std::sqrt(v[3] * v[3] + v[4] * v[4] + v[5] * v[5] + v[6] * v[6]) < 1e-6) throw Error(option + ": zero quaternion");
  return pose_from_xyz_quat(v);
}

std::shared_ptr<void> limit_threads(int threads) {
  if (threads < 0) throw Error("--threads: must be >= 0");
  if (threads == 0) return nullptr;
  return std::make_shared<tbb::global_control>(tbb::global_control::max_allowed_parallelism, threads);
}

}  // namespace gcmap::cli

int main(int argc, char** argv) {
  gcmap::keep_large_buffers_in_heap();
  // Past a file-size limit, fail the write (and keep the previous outputs) instead of dying.
  std::signal(SIGXFSZ, SIG_IGN);
  auto logger = spdlog::stderr_color_mt("gcmap");
  logger->set_pattern("[%l] %v");
  spdlog::set_default_logger(logger);

  CLI::App app{"gcmap: globally consistent 3D LiDAR mapping by global matching-cost minimization"};
  app.require_subcommand(1);
  app.set_help_all_flag("--help-all", "Help for every sub-command");
  gcmap::cli::Runner run;
  gcmap::cli::add_register(app, run);
  gcmap::cli::add_optimize(app, run);
  gcmap::cli::add_simulate(app, run);
  gcmap::cli::add_eval(app, run);
  gcmap::cli::add_mme(app, run);
  gcmap::cli::add_map(app, run);
  gcmap::cli::add_demo(app, run);
  gcmap::cli::add_config(app, run);
  gcmap::cli::add_session(app, run);
  gcmap::cli::add_localize(app, run);
  gcmap::cli::add_merge(app, run);
  gcmap::cli::add_render(app, run);
  gcmap::cli::add_plot(app, run);
  gcmap::cli::add_view(app, run);
  gcmap::cli::add_bag_info(app, run);
  gcmap::cli::add_calibrate(app, run);
  gcmap::cli::add_export(app, run);
  gcmap::cli::add_inspect(app, run);
  app.set_version_flag("--version", "gcmap " GCMAP_VERSION);
  for (CLI::App* sub : app.get_subcommands({})) sub->set_version_flag("--version", "gcmap " GCMAP_VERSION);

  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) { return app.exit(e); } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) { return app.exit(e); } catch (const CLI::ParseError& e) {
    std::cerr << "gcmap: " << e.what() << " (see --help)\n";
    return 2;
  }
  try {
    return run ? run() : 2;
  } catch (const gcmap::Error& e) {
    std::cerr << "gcmap: " << e.what() << "\n";
    return 2;
  } catch (const std::bad_alloc&) {
    std::cerr << "gcmap: out of memory\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "gcmap: " << e.what() << "\n";
    return 2;
  }
}
