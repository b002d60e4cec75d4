#pragma once
// The one config of a run: a section per module with the paper's defaults (Koide et al., RA-L
// 2021), loadable from YAML. Every key is optional; an unknown key is an error naming it. The
// modules below mapping/ define their own sections (PreprocessConfig, OdometryConfig, LoopConfig);
// the sections of mapping/ and of the session commands above it are defined here. Each key's
// meaning, unit, valid range and reading module are in the one table of config.cpp (`visit`),
// which loading, dumping, validation and docs/config.md all follow.
#include <string>
#include <variant>
#include <vector>

#include "gcmap/graph/imu_preintegration.hpp"
#include "gcmap/graph/sparse_solver.hpp"
#include "gcmap/loop/loop_closure.hpp"
#include "gcmap/odometry/odometry.hpp"
#include "gcmap/odometry/preprocess_scan.hpp"

namespace gcmap {

// full: a factor to every overlapping past submap (the paper); sliding_window: only the last K.
enum class GlobalMode { full, sliding_window };
// vgicp: matching-cost factors (the paper); se3: relative poses from scan matching (its ablation).
enum class FactorSource { vgicp, se3 };
// always: every factor at every LM iteration (the paper); moved: only factors whose poses moved
// more than global.relinearize_threshold since their last linearization (graph/lazy_backend.hpp).
enum class Relinearize { always, moved };
// The names used in YAML and on the command line ("full", "sliding-window", "vgicp", "se3", "always", "moved").
const char* to_string(GlobalMode mode);
const char* to_string(FactorSource source);
const char* to_string(Relinearize policy);
const char* to_string(LinearSolver solver);  // "eigen", "cholmod"
// Throws Error naming `key` when the text is none of the names.
GlobalMode parse_global_mode(const std::string& text, const std::string& key);
FactorSource parse_factor_source(const std::string& text, const std::string& key);

struct LocalMappingConfig {
  double th_max = 0.95;           // skip a frame whose overlap with the last keyframe exceeds this
  double th_min = 0.10;           // close the submap when overlap(first, last) falls below this
  int max_keyframes = 15;         // N_max
  double voxel_resolution = 0.5;  // keyframe voxel maps for the in-submap factors
  double submap_downsample = 0.1;
  int max_submap_points = 60000;
  int factor_source_points = 0;  // > 0: keyframe points used as the source of in-submap factors (0: all)
  int max_iterations = 20;
  double relative_error_tol = 1e-4;  // LM stops once a step gains less than this fraction
  // > 0: the in-submap matching costs weight each point by c^2 / (c^2 + m2) (MatchingCostFactor).
  double robust_width = 0.0;
  // The gyro's rotation between consecutive keyframes counts this many times what its noise gives
  // it: the matching costs count every point as independent (docs/pipeline.md).
  double gyro_weight = 10.0;
  // m per axis: the LiDAR-inertial odometry's translation between consecutive keyframes, in the
  // same factor; 0 (or without the LiDAR-inertial state): the translation is the matching costs' alone.
  double inertial_translation_sigma = 0.05;
};

struct GlobalMappingConfig {
  double th_min = 0.025;          // th_min_G: overlap needed for a matching-cost factor
  double voxel_resolution = 0.5;  // r_G (see README: 1 m tilts noisy maps)
  GlobalMode mode = GlobalMode::full;
  int window = 5;  // sliding-window: connect to this many predecessors
  FactorSource factor = FactorSource::vgicp;
  int max_iterations = 10;           // per insertion (warm-started)
  double relative_error_tol = 1e-4;  // per insertion; the final optimization runs to 1e-6
  int final_iterations = 50;
  Relinearize relinearize = Relinearize::moved;
  // Norm of a factor's relative-pose change [rad, m] since its linearization; lower stays closer
  // to `always` at more cost (docs/benchmarks.md). GLIM's iSAM2 uses 0.1.
  double relinearize_threshold = 0.01;
  // Per LM iteration of an insertion, at most this many moved factors are linearized anew (those
  // that moved most; 0: no limit), which bounds an insertion's cost where a revisit moves much of
  // the graph; the final optimization has no limit.
  int max_relinearizations = 0;
  LinearSolver linear_solver = LinearSolver::automatic;  // LM's sparse solve (graph/sparse_solver.hpp)
  // Points of a submap used as the source of its matching-cost factors and overlaps (an even
  // subsample; target voxel maps keep every point). The global graph's cost is linear in it.
  int factor_source_points = 20000;
  // Matching-cost factors a new submap gets at most: to its predecessor and the past submaps it
  // overlaps most (0: to every one above th_min). A revisit overlaps many consecutive past submaps
  // that tell much the same; each factor costs every later optimization.
  int max_new_factors = 12;
  // A matching-cost factor held along one translation by less than this fraction of the best is
  // blind along it (0: off).
  double min_conditioning = 0.03;
  // > 0: the matching costs weight each point by c^2 / (c^2 + m2) (MatchingCostFactor).
  double robust_width = 0.0;
};

// Localization on a prior map (gcmap localize).
struct LocalizationConfig {
  // A frame tracks while at least this fraction of its points fall in voxels of the prior map
  // (at global.voxel_resolution); below it the frame is lost and global initialization runs.
  double min_overlap = 0.3;
  double submap_radius = 120.0;  // m: prior submaps whose origin is this close are candidates
  // ... of which those overlapping the frame most are matched, at most this many: cost grows with
  // each, accuracy hardly.
  int max_submaps = 8;
  // Global initialization: a ScanContext candidate is accepted when GICP aligns at least this
  // fraction of the scan within loop.inlier_distance (a scan sees beyond one submap).
  double min_inlier_fraction = 0.3;
  // ... and their point-to-plane RMSE is at most this (m): one noisy scan against a submap, looser
  // than loop.max_inlier_rmse for two submaps; a strict bound finds the place much later.
  double max_inlier_rmse = 0.07;
  int relocalize_every = 5;  // frames between global initialization attempts while lost
};

// Merging sessions (gcmap merge): cross-session places are found and verified with loop.*.
struct MergeConfig {
  // Looser than loop.max_descriptor_distance: another session passes a place in another lane or
  // direction; the GICP verification (below) rejects the wrong ones.
  double max_descriptor_distance = 0.3;
  int max_verifications = 10;  // GICP checks (distinct submap pairs, best ScanContext candidates first) per session to place
  // A place between sessions is accepted when GICP aligns at least min_inlier_fraction of the
  // source submap within loop.inlier_distance, at a point-to-plane RMSE of at most
  // loop.max_inlier_rmse or of at most max_rmse_ratio times the RMSE at which each of the two
  // submaps meets its neighbour in its own session (the noise the sessions themselves show): no
  // absolute bound separates true places in noisy sessions from wrong ones in clean sessions.
  double min_inlier_fraction = 0.5;
  double max_rmse_ratio = 1.5;
  int max_iterations = 50;  // joint LM over all sessions
};

// Per-beam elevation offsets estimated by `gcmap map` itself before mapping, from the odometry of
// the first frames (mapping/self_calibration.hpp), when no calibration file is given.
struct CalibrationConfig {
  bool estimate_elevation = true;
  int frames = 300;          // the first frames read for it
  int every = 5;             // every n-th of them enters the estimate
  int passes = 2;            // odometry passes, each on the scans corrected by the previous estimate
  double min_offset_deg = 0.05;  // smaller offsets are left out
  double downsample = 0.5;       // m: voxels of the scans the passes' odometry registers
  double min_travel = 40.0;  // m the sensor must move over those frames, else no estimate
};

// The run-quality report (mapping/quality.hpp): what its flags take.
struct QualityConfig {
  double degenerate_conditioning = 0.05;  // a frame's translation conditioning below this: degenerate
  // Two overlapping submaps disagree when re-registering one onto the other moves it more than
  // this many times the noise (QualityReport) and by at least min_shift m.
  double inconsistent_factor = 4.0;
  double min_shift = 0.02;
  double pair_radius = 20.0;       // m between submap origins: pairs compared
  double min_pair_inliers = 0.3;   // a pair overlapping less after registration says nothing
  double coarse_resolution = 2.0;  // m: voxels of the coarse registration of a pair that drifted apart
  double stamp_gap_factor = 1.5;   // a stamp interval over this times the median one is an anomaly
};

// GNSS fixes as position factors of the global graph (`gcmap map --gnss`, gnss.txt).
struct GnssConfig {
  // m: the antenna in the LiDAR (sensor) frame.
  double lever_arm_x = 0.0, lever_arm_y = 0.0, lever_arm_z = 0.0;
  double huber_width = 3.0;        // sigmas: beyond, a fix's pull stays constant (multipath)
  double align_distance = 30.0;    // m the fixes must span before the map is turned onto them
  double max_gap = 0.5;            // s: a fix between scans further apart than this is skipped
  double outlier_threshold = 5.0;  // sigmas: a fix further from the final estimate counts as rejected
};

struct OutputConfig {
  double map_resolution = 0.1;
  bool pcd = false;
};

// One key of the config table (mapping/config.cpp), as `gcmap config --describe` and docs/config.md
// show it: values as YAML text, the range as words.
struct ConfigKeyDoc {
  std::string section, key, type, default_value, unit, range, module, meaning;
};

struct MappingConfig {
  PreprocessConfig preprocess;
  CalibrationConfig calibration;
  OdometryConfig odometry;
  LocalMappingConfig local;
  GlobalMappingConfig global;
  LoopConfig loop;
  LocalizationConfig localize;
  MergeConfig merge;
  GnssConfig gnss;
  ImuConfig imu;
  OutputConfig output;
  QualityConfig quality;

  // Throws Error("PATH: ...") naming the offending key.
  static MappingConfig load(const std::string& path);
  // The same on YAML text in memory (fuzzed); `name` stands for the path in messages.
  static MappingConfig parse(const std::string& yaml, const std::string& name);
  std::string to_yaml() const;
  // Every key in its range (the table's), then the checks between keys; throws Error naming the key.
  void validate() const;
  // Every key with its default, unit, range, module and meaning, in YAML order.
  static std::vector<ConfigKeyDoc> documentation();

  // Every field by its "section.key" name, for front ends that set fields one by one (the Python
  // package); enums as their YAML names. Unknown keys and values of the wrong type throw Error
  // naming the key; set() does not validate (fields checked together may be set in any order).
  using Value = std::variant<bool, int, double, std::string>;
  static std::vector<std::string> keys();
  Value get(const std::string& key) const;
  void set(const std::string& key, const Value& value);
};

// The documentation of every key: a plain-text table (`gcmap config --describe`) and docs/config.md.
std::string config_reference_text();
std::string config_reference_markdown();

}  // namespace gcmap
