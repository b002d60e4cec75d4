#include <cstdio>
#include <filesystem>

#include "commands.hpp"
#include "gcmap/session/session.hpp"
#include "progress.hpp"

namespace gcmap::cli {

void add_session(CLI::App& app, Runner& run) {
  auto* cmd = app.add_subcommand("session", "Inspect a mapping session (OUT/session of gcmap map)");
  cmd->require_subcommand(1);
  auto dir = std::make_shared<std::string>();
  auto json = std::make_shared<bool>(false);
  auto* info = cmd->add_subcommand("info", "What a session holds: submaps, frames, extent, size on disk, version");
  info->add_option("OUT", *dir, "The output folder of gcmap map (or its session/ folder)")->required();
  info->add_flag("--json", *json, "Print JSON instead of a table");
  info->callback([dir, json, &run] {
    run = [dir, json] {
      namespace fs = std::filesystem;
      const std::string folder =
          fs::exists(fs::path(*dir) / "session" / "manifest.yaml") ? (fs::path(*dir) / "session").string() : *dir;
      Progress loading("loading session: submap", 0, false);
      const Session s = read_session(folder, loading.callback());
      loading.finish();
      const SessionInfo i = session_info(s, folder);
      const Eigen::Vector3d size = i.extent.isEmpty() ? Eigen::Vector3d::Zero() : Eigen::Vector3d(i.extent.sizes());
      if (*json) {
        std::printf(
            "{\"version\":%d,\"created_by\":\"%s\",\"frames\":%zu,\"submaps\":%zu,\"keyframes\":%zu,\"points\":%zu,"
            "\"intensities\":%s,\"factors\":%zu,\"extent_m\":[%.3f,%.3f,%.3f],\"bytes\":%ju}\n",
            i.version, i.created_by.c_str(), i.frames, i.submaps, i.keyframes, i.points, i.intensities ? "true" : "false",
            i.factors, size.x(), size.y(), size.z(), i.bytes);
        return 0;
      }
      std::printf("session     %s (format version %d, written by %s)\n", folder.c_str(), i.version, i.created_by.c_str());
      std::printf("frames      %zu (%zu keyframes)\n", i.frames, i.keyframes);
      std::printf("submaps     %zu, %zu points with covariances%s\n", i.submaps, i.points,
                  i.intensities ? " and intensities" : " (no intensity)");
      std::printf("factors     %zu in the global graph\n", i.factors);
      std::printf("extent      %.1f x %.1f x %.1f m\n", size.x(), size.y(), size.z());
      std::printf("on disk     %.1f MB\n", i.bytes / 1e6);
      return 0;
    };
  });
}

}  // namespace gcmap::cli
