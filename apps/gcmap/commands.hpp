#pragma once
#include <CLI/CLI.hpp>
#include <functional>
#include <memory>
#include <string>

#include <Eigen/Geometry>

#include "gcmap/io/json.hpp"

namespace gcmap::cli {

// Each sub-command registers its options and sets `run` (returns the exit code) when selected.
using Runner = std::function<int()>;

void add_register(CLI::App& app, Runner& run);
void add_optimize(CLI::App& app, Runner& run);
void add_simulate(CLI::App& app, Runner& run);
void add_eval(CLI::App& app, Runner& run);
void add_mme(CLI::App& app, Runner& run);
void add_map(CLI::App& app, Runner& run);
void add_demo(CLI::App& app, Runner& run);
void add_config(CLI::App& app, Runner& run);
void add_session(CLI::App& app, Runner& run);
void add_localize(CLI::App& app, Runner& run);
void add_merge(CLI::App& app, Runner& run);
void add_render(CLI::App& app, Runner& run);
void add_plot(CLI::App& app, Runner& run);
void add_view(CLI::App& app, Runner& run);
void add_bag_info(CLI::App& app, Runner& run);
void add_calibrate(CLI::App& app, Runner& run);
void add_export(CLI::App& app, Runner& run);
void add_inspect(CLI::App& app, Runner& run);

// "x y z qx qy qz qw" -> pose; throws Error naming the option.
Eigen::Isometry3d parse_pose_option(const std::string& option, const std::string& text);

// Applies --threads (0 = all cores) for the lifetime of the returned object.
std::shared_ptr<void> limit_threads(int threads);

}  // namespace gcmap::cli
