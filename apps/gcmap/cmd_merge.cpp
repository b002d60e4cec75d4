#include <algorithm>
#include <cstdio>
#include <filesystem>

#include "commands.hpp"
#include "gcmap/core/error.hpp"
#include "gcmap/cuda/cuda_backend.hpp"
#include "gcmap/io/file.hpp"
#include "gcmap/io/point_cloud_io.hpp"
#include "gcmap/io/trajectory_io.hpp"
#include "gcmap/mapping/mapper.hpp"
#include "gcmap/session/merge.hpp"
#include "gcmap/session/session.hpp"
#include "progress.hpp"

namespace gcmap::cli {

namespace {

namespace fs = std::filesystem;

struct MergeOptions {
  std::vector<std::string> inputs;
  std::string output, config_file, device = "auto";
  int threads = 0;
};

// The connected sessions as one: submaps and frames concatenated in input order.
Session merged_session(const std::vector<Session>& sessions, const MergeResult& r, const MappingConfig& config) {
  Session m;
  m.config = config;
  m.T_world_submap = r.T_merged_submap;
  m.factors = r.factors;
  int frame_offset = 0;
  for (size_t k = 0; k < sessions.size(); ++k) {
    if (!r.connected[k]) continue;
    for (Submap s : sessions[k].submaps) {
      s.id = static_cast<int>(m.submaps.size());
      for (int& f : s.keyframes) f += frame_offset;
      m.submaps.push_back(std::move(s));
    }
    m.trajectory.insert(m.trajectory.end(), r.trajectories[k].begin(), r.trajectories[k].end());
    m.stamps.insert(m.stamps.end(), sessions[k].stamps.begin(), sessions[k].stamps.end());
    frame_offset += static_cast<int>(sessions[k].trajectory.size());
  }
  return m;
}

// Why the merged map has no intensity (empty when it has): the first connected session without.
std::string missing_intensity(const MergeOptions& o, const std::vector<Session>& sessions, const MergeResult& r) {
  for (size_t k = 0; k < sessions.size(); ++k) {
    if (!r.connected[k] || have_intensities(sessions[k].submaps)) continue;
    return o.inputs[k] + (sessions[k].version < 2 ? " is a version 1 session, which kept no intensity"
                                                  : " was mapped from scans without intensity");
  }
  return "";
}

Json merge_report(const MergeOptions& o, const MergeResult& r) {
  Json j = Json::object();
  Json sessions = Json::array();
  for (size_t k = 0; k < o.inputs.size(); ++k) {
    Json s = Json::object();
    s["input"] = o.inputs[k];
    s["connected"] = static_cast<bool>(r.connected[k]);
    const SessionPlacement& p = r.placements[k];
    if (p.anchor >= 0) {
      s["placed_against"] = p.anchor;
      s["submap"] = p.source;
      s["anchor_submap"] = p.target;
      s["descriptor_distance"] = p.descriptor_distance;
      s["inlier_fraction"] = p.inlier_fraction;
      s["inlier_rmse"] = p.inlier_rmse;
    }
    sessions.push_back(s);
  }
  j["sessions"] = sessions;
  Json checks = Json::array();
  for (const SessionPlacement& c : r.checks) {
    Json x = Json::object();
    x["session"] = c.session;
    x["submap"] = c.source;
    x["anchor"] = c.anchor;
    x["anchor_submap"] = c.target;
    x["descriptor_distance"] = c.descriptor_distance;
    x["inlier_fraction"] = c.inlier_fraction;
    x["inlier_rmse"] = c.inlier_rmse;
    x["allowed_rmse"] = c.allowed_rmse;
    x["accepted"] = c.accepted;
    checks.push_back(x);
  }
  j["verifications"] = checks;
  j["submaps"] = r.T_merged_submap.size();
  j["factors"] = r.factors.size();
  j["cross_session_factors"] = r.cross_factors;
  j["iterations"] = r.optimization.iterations;
  j["initial_error"] = r.optimization.initial_error;
  j["final_error"] = r.optimization.final_error;
  j["placement_ms"] = r.placement_ms;
  j["total_ms"] = r.total_ms;
  return j;
}

int merge(const MergeOptions& o) {
  const auto threads = limit_threads(o.threads);
  if (o.inputs.size() < 2) throw Error("merge: give at least two session folders");
  std::vector<Session> sessions;
  std::vector<MergeInput> inputs;
  for (const std::string& in : o.inputs) {
    const std::string folder = fs::exists(fs::path(in) / "session") ? (fs::path(in) / "session").string() : in;
    Progress loading("loading " + folder + ": submap", 0, false);
    sessions.push_back(read_session(folder, loading.callback()));
    loading.finish();
    const Session& s = sessions.back();
    inputs.push_back({in, s.submaps, s.T_world_submap, s.factors, s.trajectory});
  }
  const MappingConfig config = o.config_file.empty() ? sessions[0].config : MappingConfig::load(o.config_file);
  const MergeResult r = merge_sessions(inputs, config, cuda::make_backend(parse_device(o.device, "--device")));
  const fs::path out(o.output);
  std::error_code ec;
  fs::create_directories(out, ec);
  if (ec) throw Error(o.output + ": cannot create output folder (" + ec.message() + ")");
  const Session m = merged_session(sessions, r, config);
  write_session((out / "session").string(), m);
  std::string unconnected;
  for (size_t k = 0; k < sessions.size(); ++k) {
    if (!r.connected[k]) {
      unconnected += (unconnected.empty() ? "" : ", ") + o.inputs[k];
      continue;
    }
    Trajectory t;
    t.poses = r.trajectories[k];
    t.stamps = sessions[k].stamps;
    write_trajectory((out / ("trajectory_" + std::to_string(k) + ".kitti")).string(), t);
  }
  write_ply((out / "map.ply").string(), assemble_map(m.submaps, m.T_world_submap, config.output.map_resolution));
  if (const std::string why = missing_intensity(o, sessions, r); !why.empty())
    std::fprintf(stderr, "map.ply has no intensity: %s.\n", why.c_str());
  write_file_atomic((out / "merge.json").string(), [&](std::ostream& s) { s << merge_report(o, r).dump() << "\n"; });
  std::fprintf(stderr, "Merged %zu of %zu sessions in %.1f s: %zu submaps, %zu factors between sessions, %d LM iterations.\n",
               sessions.size() - std::count(r.connected.begin(), r.connected.end(), false), sessions.size(), r.total_ms / 1000.0,
               m.submaps.size(), r.cross_factors, r.optimization.iterations);
  if (!unconnected.empty())
    std::fprintf(stderr, "Unconnected (no verified place shared with the others, left out): %s\n", unconnected.c_str());
  std::fprintf(stderr,
               "Wrote %s: session/, trajectory_K.kitti per connected input K (the first input's first frame the identity), "
               "map.ply, merge.json.\n",
               o.output.c_str());
  return 0;
}

}  // namespace

void add_merge(CLI::App& app, Runner& run) {
  auto o = std::make_shared<MergeOptions>();
  auto* cmd = app.add_subcommand("merge", "Merge the sessions of several gcmap map runs into one frame");
  cmd->add_option("inputs", o->inputs, "Output folders of gcmap map (or their session/ folders), the first one's frame kept")
      ->required();
  cmd->add_option("-o,--output", o->output, "Output folder")->required();
  cmd->add_option("--config", o->config_file, "YAML configuration (merge.*, loop.*; default: the first session's)");
  cmd->add_option("--device", o->device, "cpu, cuda or auto")->capture_default_str();
  cmd->add_option("--threads", o->threads, "Worker threads (0 = all cores)")->capture_default_str();
  cmd->callback([o, &run] { run = [o] { return merge(*o); }; });
}

}  // namespace gcmap::cli
