#include "gcmap/mapping/config.hpp"

#include <yaml-cpp/yaml.h>

#include <charconv>
#include <cmath>
#include <functional>
#include <map>
#include <optional>
#include <sstream>

#include "gcmap/core/error.hpp"
#include "gcmap/io/file.hpp"

namespace gcmap {

namespace {

template <typename E, size_t N>
E parse_enum(const std::string& text, const std::string& key, const std::pair<E, const char*> (&names)[N]) {
  std::string list;
  for (const auto& [value, name] : names) {
    if (text == name) return value;
    list += (list.empty() ? "" : ", ") + std::string(name);
  }
  throw Error(key + " must be one of " + list + ", got '" + text + "'");
}

constexpr std::pair<GlobalMode, const char*> kGlobalModes[] = {{GlobalMode::full, "full"},
                                                               {GlobalMode::sliding_window, "sliding-window"}};
constexpr std::pair<FactorSource, const char*> kFactorSources[] = {{FactorSource::vgicp, "vgicp"}, {FactorSource::se3, "se3"}};
constexpr std::pair<Relinearize, const char*> kRelinearize[] = {{Relinearize::always, "always"}, {Relinearize::moved, "moved"}};
constexpr std::pair<LinearSolver, const char*> kLinearSolvers[] = {
    {LinearSolver::eigen, "eigen"}, {LinearSolver::cholmod, "cholmod"}, {LinearSolver::automatic, "auto"}};

template <typename E>
E parse_config_enum(const std::string& text, const std::string& key) {
  if constexpr (std::is_same_v<E, GlobalMode>) return parse_enum(text, key, kGlobalModes);
  else if constexpr (std::is_same_v<E, FactorSource>) return parse_enum(text, key, kFactorSources);
  else if constexpr (std::is_same_v<E, Relinearize>) return parse_enum(text, key, kRelinearize);
  else return parse_enum(text, key, kLinearSolvers);
}

// Visits every (section, key, field) once, for loading and dumping alike.
template <typename Config, typename Visitor>
void visit(Config& c, Visitor&& v) {
  v("preprocess", "min_range", c.preprocess.min_range);
  v("preprocess", "max_range", c.preprocess.max_range);
  v("preprocess", "downsample", c.preprocess.downsample);
  v("preprocess", "num_neighbors", c.preprocess.num_neighbors);
  v("preprocess", "elevation_sigma_deg", c.preprocess.elevation_sigma_deg);
  v("preprocess", "elevation_calibration", c.preprocess.elevation_calibration);
  v("preprocess", "kitti_vertical_correction", c.preprocess.kitti_vertical_correction);
  v("preprocess", "remove_dynamic_labels", c.preprocess.remove_dynamic_labels);
  v("preprocess", "deskew", c.preprocess.deskew);
  v("preprocess", "redeskew", c.preprocess.redeskew);
  v("preprocess", "deskew_from_azimuth", c.preprocess.deskew_from_azimuth);
  v("preprocess", "sweep_period", c.preprocess.sweep_period);
  v("preprocess", "sweep_start_deg", c.preprocess.sweep_start_deg);
  v("preprocess", "sweep_clockwise", c.preprocess.sweep_clockwise);
  v("odometry", "voxel_resolution", c.odometry.voxel_resolution);
  v("odometry", "model_keyframes", c.odometry.model_keyframes);
  v("odometry", "keyframe_distance", c.odometry.keyframe_distance);
  v("odometry", "keyframe_angle_deg", c.odometry.keyframe_angle_deg);
  v("odometry", "max_iterations", c.odometry.max_iterations);
  v("odometry", "max_interval_ratio", c.odometry.max_interval_ratio);
  v("odometry", "max_gap", c.odometry.max_gap);
  v("odometry", "retry_distance", c.odometry.retry_distance);
  v("odometry", "retry_inlier_fraction", c.odometry.retry_inlier_fraction);
  v("odometry", "start_voxel_resolution", c.odometry.start_voxel_resolution);
  v("local", "th_max", c.local.th_max);
  v("local", "th_min", c.local.th_min);
  v("local", "max_keyframes", c.local.max_keyframes);
  v("local", "voxel_resolution", c.local.voxel_resolution);
  v("local", "submap_downsample", c.local.submap_downsample);
  v("local", "max_submap_points", c.local.max_submap_points);
  v("local", "factor_source_points", c.local.factor_source_points);
  v("local", "max_iterations", c.local.max_iterations);
  v("local", "relative_error_tol", c.local.relative_error_tol);
  v("global", "th_min", c.global.th_min);
  v("global", "voxel_resolution", c.global.voxel_resolution);
  v("global", "mode", c.global.mode);
  v("global", "window", c.global.window);
  v("global", "factor", c.global.factor);
  v("global", "max_iterations", c.global.max_iterations);
  v("global", "relative_error_tol", c.global.relative_error_tol);
  v("global", "final_iterations", c.global.final_iterations);
  v("global", "relinearize", c.global.relinearize);
  v("global", "relinearize_threshold", c.global.relinearize_threshold);
  v("global", "max_relinearizations", c.global.max_relinearizations);
  v("global", "linear_solver", c.global.linear_solver);
  v("global", "factor_source_points", c.global.factor_source_points);
  v("loop", "enabled", c.loop.enabled);
  v("loop", "rings", c.loop.scan_context.rings);
  v("loop", "sectors", c.loop.scan_context.sectors);
  v("loop", "max_radius", c.loop.scan_context.max_radius);
  v("loop", "lidar_height", c.loop.scan_context.lidar_height);
  v("loop", "exclude_recent", c.loop.exclude_recent);
  v("loop", "num_candidates", c.loop.num_candidates);
  v("loop", "max_descriptor_distance", c.loop.max_descriptor_distance);
  v("loop", "verification_downsample", c.loop.verification_downsample);
  v("loop", "inlier_distance", c.loop.inlier_distance);
  v("loop", "min_inlier_fraction", c.loop.min_inlier_fraction);
  v("loop", "max_inlier_rmse", c.loop.max_inlier_rmse);
  v("loop", "rotation_sigma_deg", c.loop.rotation_sigma_deg);
  v("loop", "translation_sigma", c.loop.translation_sigma);
  v("loop", "tukey_width", c.loop.tukey_width);
  v("loop", "tukey_offset", c.loop.tukey_offset);
  v("localize", "min_overlap", c.localize.min_overlap);
  v("localize", "submap_radius", c.localize.submap_radius);
  v("localize", "max_submaps", c.localize.max_submaps);
  v("localize", "min_inlier_fraction", c.localize.min_inlier_fraction);
  v("localize", "max_inlier_rmse", c.localize.max_inlier_rmse);
  v("localize", "relocalize_every", c.localize.relocalize_every);
  v("merge", "max_descriptor_distance", c.merge.max_descriptor_distance);
  v("merge", "max_verifications", c.merge.max_verifications);
  v("merge", "min_inlier_fraction", c.merge.min_inlier_fraction);
  v("merge", "max_rmse_ratio", c.merge.max_rmse_ratio);
  v("merge", "max_iterations", c.merge.max_iterations);
  v("output", "map_resolution", c.output.map_resolution);
  v("output", "pcd", c.output.pcd);
}

// Every section and key must be a known plain name.
void check_known_keys(const YAML::Node& root, const std::string& path) {
  std::map<std::string, std::map<std::string, bool>> known;
  MappingConfig defaults;
  visit(defaults, [&](const char* s, const char* k, auto&) { known[s][k] = true; });
  for (const auto& section : root) {
    if (!section.first.IsScalar()) throw Error(path + ": a section name must be a plain word");
    const std::string s = section.first.Scalar();
    if (!known.count(s)) throw Error(path + ": unknown section '" + s + "'");
    if (!section.second.IsMap()) throw Error(path + ": section '" + s + "' must be a mapping");
    for (const auto& kv : section.second) {
      if (!kv.first.IsScalar()) throw Error(path + ": a key in section '" + s + "' must be a plain word");
      const std::string k = kv.first.Scalar();
      if (!known[s].count(k)) throw Error(path + ": unknown key '" + s + "." + k + "'");
    }
  }
}

// Doubles as the shortest text that reads back to the same value, so a dumped config reloads exactly.
std::string format_double(double v) {
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof(buf), v);
  return std::string(buf, r.ptr);
}

}  // namespace

const char* to_string(GlobalMode mode) { return kGlobalModes[static_cast<int>(mode)].second; }
const char* to_string(FactorSource source) { return kFactorSources[static_cast<int>(source)].second; }
const char* to_string(Relinearize policy) { return kRelinearize[static_cast<int>(policy)].second; }
const char* to_string(LinearSolver solver) { return kLinearSolvers[static_cast<int>(solver)].second; }
GlobalMode parse_global_mode(const std::string& text, const std::string& key) { return parse_config_enum<GlobalMode>(text, key); }
FactorSource parse_factor_source(const std::string& text, const std::string& key) {
  return parse_config_enum<FactorSource>(text, key);
}

MappingConfig MappingConfig::load(const std::string& path) { return parse(read_file(path), path); }

MappingConfig MappingConfig::parse(const std::string& text, const std::string& path) {
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::Exception& e) {
    throw Error(path + ": YAML syntax error at line " + std::to_string(e.mark.line + 1));
  }
  MappingConfig c;
  if (root.IsNull()) return c;
  if (!root.IsMap()) throw Error(path + ": expected a mapping of sections");
  check_known_keys(root, path);
  const YAML::Node& croot = root;
  visit(c, [&](const char* s, const char* k, auto& field) {
    const YAML::Node section = croot[s];
    if (!section.IsDefined() || !section.IsMap()) return;
    const YAML::Node node = section[k];
    if (!node.IsDefined()) return;
    using T = std::decay_t<decltype(field)>;
    const std::string key = std::string(s) + "." + k;
    try {
      if constexpr (std::is_enum_v<T>) field = parse_config_enum<T>(node.as<std::string>(), key);
      else field = node.as<T>();
    } catch (const Error& e) {
      throw Error(path + ": " + e.what());
    } catch (const YAML::Exception&) {
      throw Error(path + ": key '" + key + "' has an unreadable value");
    }
    if constexpr (std::is_floating_point_v<T>)
      if (!std::isfinite(field)) throw Error(path + ": key '" + key + "' must be a finite number");
  });
  try {
    c.validate();
  } catch (const Error& e) {
    throw Error(path + ": " + e.what());
  }
  return c;
}

namespace {

// YAML double-quoted scalar: a path may hold ': ' or '#', and an empty one must stay a string. A
// line break or tab in single quotes would be folded into a space when read back; escaped, it
// survives the round trip.
std::string double_quoted(const std::string& text) {
  std::string out = "\"";
  for (const char ch : text) {
    const auto byte = static_cast<unsigned char>(ch);
    if (ch == '"' || ch == '\\') {
      out += '\\';
      out += ch;
    } else if (byte < 0x20 || byte == 0x7f) {
      static const char hex[] = "0123456789abcdef";
      out += "\\x";
      out += hex[byte >> 4];
      out += hex[byte & 15];
    } else {
      out += ch;
    }
  }
  return out + "\"";
}

}  // namespace

std::string MappingConfig::to_yaml() const {
  std::ostringstream out;
  std::string current;
  MappingConfig copy = *this;
  visit(copy, [&](const char* s, const char* k, auto& field) {
    if (current != s) {
      out << s << ":\n";
      current = s;
    }
    out << "  " << k << ": ";
    using T = std::decay_t<decltype(field)>;
    if constexpr (std::is_same_v<T, bool>) out << (field ? "true" : "false");
    else if constexpr (std::is_enum_v<T>) out << to_string(field);
    else if constexpr (std::is_floating_point_v<T>) out << format_double(field);
    else if constexpr (std::is_same_v<T, std::string>) out << double_quoted(field);
    else out << field;
    out << "\n";
  });
  return out.str();
}

void MappingConfig::validate() const {
  auto need = [](bool ok, const std::string& what) {
    if (!ok) throw Error(what);
  };
  need(preprocess.min_range >= 0 && preprocess.max_range > preprocess.min_range, "preprocess.max_range must exceed preprocess.min_range >= 0");
  need(preprocess.downsample > 0, "preprocess.downsample must be positive");
  need(preprocess.num_neighbors >= 4, "preprocess.num_neighbors must be >= 4");
  need(preprocess.elevation_sigma_deg >= 0 && preprocess.elevation_sigma_deg < 10,
       "preprocess.elevation_sigma_deg must be in [0, 10)");
  need(odometry.voxel_resolution > 0, "odometry.voxel_resolution must be positive");
  need(odometry.start_voxel_resolution >= odometry.voxel_resolution,
       "odometry.start_voxel_resolution must be at least odometry.voxel_resolution");
  need(odometry.model_keyframes >= 1, "odometry.model_keyframes must be >= 1");
  need(odometry.max_iterations >= 1, "odometry.max_iterations must be >= 1");
  need(preprocess.sweep_period > 0 && std::isfinite(preprocess.sweep_start_deg),
       "preprocess.sweep_period must be positive, preprocess.sweep_start_deg finite");
  need(odometry.max_interval_ratio >= 1 && odometry.max_gap > 0, "odometry.max_interval_ratio must be >= 1, odometry.max_gap positive");
  need(odometry.retry_distance > 0 && odometry.retry_inlier_fraction >= 0 && odometry.retry_inlier_fraction <= 1,
       "odometry.retry_distance must be positive, odometry.retry_inlier_fraction in [0, 1]");
  need(local.th_max > 0 && local.th_max <= 1, "local.th_max must be in (0, 1]");
  need(local.th_min >= 0 && local.th_min < local.th_max, "local.th_min must be in [0, local.th_max)");
  need(local.max_keyframes >= 2, "local.max_keyframes must be >= 2");
  need(local.voxel_resolution > 0 && local.submap_downsample > 0, "local resolutions must be positive");
  need(local.max_submap_points >= 1000, "local.max_submap_points must be >= 1000");
  need(global.factor_source_points >= 1000, "global.factor_source_points must be >= 1000");
  need(local.factor_source_points == 0 || local.factor_source_points >= 1000, "local.factor_source_points must be 0 or >= 1000");
  need(global.th_min >= 0 && global.th_min <= 1, "global.th_min must be in [0, 1]");
  need(global.voxel_resolution > 0, "global.voxel_resolution must be positive");
  need(global.window >= 1, "global.window must be >= 1");
  need(global.relinearize_threshold >= 0, "global.relinearize_threshold must be >= 0");
  need(global.max_relinearizations >= 0, "global.max_relinearizations must be >= 0 (0: no limit)");
  need(global.linear_solver != LinearSolver::cholmod || cholmod_available(),
       "global.linear_solver is cholmod, but this build has no CHOLMOD (SuiteSparse)");
  need(global.max_iterations >= 1 && global.final_iterations >= 1, "global iteration limits must be >= 1");
  need(local.relative_error_tol >= 0 && global.relative_error_tol >= 0, "relative_error_tol must be >= 0");
  need(loop.scan_context.rings >= 1 && loop.scan_context.sectors >= 2 && loop.scan_context.max_radius > 0,
       "loop.rings, loop.sectors and loop.max_radius must be positive");
  need(loop.exclude_recent >= 1 && loop.num_candidates >= 1, "loop.exclude_recent and loop.num_candidates must be >= 1");
  need(loop.max_descriptor_distance > 0 && loop.max_descriptor_distance <= 1, "loop.max_descriptor_distance must be in (0, 1]");
  need(loop.verification_downsample > 0 && loop.inlier_distance > 0 && loop.max_inlier_rmse > 0,
       "loop.verification_downsample, loop.inlier_distance and loop.max_inlier_rmse must be positive");
  need(loop.min_inlier_fraction > 0 && loop.min_inlier_fraction <= 1, "loop.min_inlier_fraction must be in (0, 1]");
  need(loop.rotation_sigma_deg > 0 && loop.translation_sigma > 0, "loop sigmas must be positive");
  need(loop.tukey_width > 0 && loop.tukey_offset >= 0, "loop.tukey_width must be positive, loop.tukey_offset >= 0");
  need(localize.min_overlap > 0 && localize.min_overlap <= 1, "localize.min_overlap must be in (0, 1]");
  need(localize.submap_radius > 0, "localize.submap_radius must be positive");
  need(localize.max_submaps >= 1, "localize.max_submaps must be >= 1");
  need(localize.min_inlier_fraction > 0 && localize.min_inlier_fraction <= 1, "localize.min_inlier_fraction must be in (0, 1]");
  need(localize.max_inlier_rmse > 0, "localize.max_inlier_rmse must be positive");
  need(localize.relocalize_every >= 1, "localize.relocalize_every must be >= 1");
  need(merge.max_descriptor_distance > 0 && merge.max_descriptor_distance <= 1, "merge.max_descriptor_distance must be in (0, 1]");
  need(merge.max_verifications >= 1 && merge.max_iterations >= 1, "merge.max_verifications and merge.max_iterations must be >= 1");
  need(merge.min_inlier_fraction > 0 && merge.min_inlier_fraction <= 1, "merge.min_inlier_fraction must be in (0, 1]");
  need(merge.max_rmse_ratio > 0, "merge.max_rmse_ratio must be positive");
  need(output.map_resolution > 0, "output.map_resolution must be positive");
}

namespace {

std::string describe(const MappingConfig::Value& value) {
  if (const auto* b = std::get_if<bool>(&value)) return *b ? "true" : "false";
  if (const auto* i = std::get_if<int>(&value)) return std::to_string(*i);
  if (const auto* d = std::get_if<double>(&value)) {
    std::ostringstream out;
    out << *d;
    return out.str();
  }
  return "'" + std::get<std::string>(value) + "'";
}

template <typename T>
T convert(const MappingConfig::Value& value, const std::string& key) {
  const auto wrong = [&](const char* what) { return Error(key + " must be " + what + ", got " + describe(value)); };
  if constexpr (std::is_same_v<T, bool>) {
    if (const auto* b = std::get_if<bool>(&value)) return *b;
    throw wrong("true or false");
  } else if constexpr (std::is_same_v<T, int>) {
    if (const auto* i = std::get_if<int>(&value)) return *i;
    const auto* d = std::get_if<double>(&value);
    if (d && std::trunc(*d) == *d && std::abs(*d) < 2e9) return static_cast<int>(*d);
    throw wrong("an integer");
  } else if constexpr (std::is_same_v<T, double>) {
    if (const auto* d = std::get_if<double>(&value)) return *d;
    if (const auto* i = std::get_if<int>(&value)) return *i;
    throw wrong("a number");
  } else if constexpr (std::is_same_v<T, std::string>) {
    if (const auto* text = std::get_if<std::string>(&value)) return *text;
    throw wrong("a file name");
  } else {
    const auto* text = std::get_if<std::string>(&value);
    if (!text) throw wrong("a name");
    return parse_config_enum<T>(*text, key);
  }
}

}  // namespace

std::vector<std::string> MappingConfig::keys() {
  std::vector<std::string> out;
  const MappingConfig defaults;
  visit(defaults, [&](const char* s, const char* k, const auto&) { out.push_back(std::string(s) + "." + k); });
  return out;
}

MappingConfig::Value MappingConfig::get(const std::string& key) const {
  std::optional<Value> out;
  visit(*this, [&](const char* s, const char* k, const auto& field) {
    if (out || key != std::string(s) + "." + k) return;
    if constexpr (std::is_enum_v<std::decay_t<decltype(field)>>) out = std::string(to_string(field));
    else out = Value(field);
  });
  if (!out) throw Error("unknown key '" + key + "'");
  return *out;
}

void MappingConfig::set(const std::string& key, const Value& value) {
  bool found = false;
  visit(*this, [&](const char* s, const char* k, auto& field) {
    if (found || key != std::string(s) + "." + k) return;
    found = true;
    field = convert<std::decay_t<decltype(field)>>(value, key);
  });
  if (!found) throw Error("unknown key '" + key + "'");
}

}  // namespace gcmap
