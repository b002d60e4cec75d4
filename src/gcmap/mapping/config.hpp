#pragma once
// One config struct per module with the paper's defaults (Koide et al., RA-L 2021), loadable
// from YAML. Every key is optional; an unknown key is an error naming it.
#include <string>
#include <variant>
#include <vector>

#include "gcmap/graph/sparse_solver.hpp"
#include "gcmap/mapping/scan_context.hpp"

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

struct PreprocessConfig {
  double min_range = 2.0;  // m: drops returns from the ego vehicle
  double max_range = 100.0;
  double downsample = 0.25;  // voxel size in m
  int num_neighbors = 10;    // covariance estimation
  // Beam elevation uncertainty added to each point's covariance (range x sigma along the beam's
  // vertical plane): a sensor with a per-beam elevation bias (factory calibration) makes far
  // ground lie off its plane by range x bias. 0 = off.
  double elevation_sigma_deg = 0.0;
  // A file of per-beam elevation offsets (`gcmap calibrate`, mapping/elevation_calibration.hpp)
  // applied to every raw scan; empty: none.
  std::string elevation_calibration;
  bool kitti_vertical_correction = true;  // 0.22 deg intrinsic correction, KITTI layouts only
  bool remove_dynamic_labels = true;      // SemanticKITTI moving classes, when labels/ exists
  // Motion compensation of scans with per-point times, by the motion the odometry registers over
  // the sweep (a velocity that changes linearly).
  bool deskew = true;
  // Each sweep deskewed again once the next one is registered, by the quadratic through the poses
  // on both sides of it (interpolated, no longer extrapolated), for the map and the odometry's model.
  bool redeskew = true;
  // Scans without per-point times from a spinning sensor: times from each point's azimuth
  // atan2(y, x), t = sweep_period * (the fraction of the turn since sweep_start_deg). The defaults
  // follow the point order of KITTI's HDL-64 files: each ring starts facing forward (+x, 0 deg) and
  // its azimuth increases, counter-clockwise seen from above.
  bool deskew_from_azimuth = false;
  double sweep_period = 0.1;  // s per turn
  double sweep_start_deg = 0.0;
  bool sweep_clockwise = false;
};

struct OdometryConfig {
  double voxel_resolution = 1.0;  // scan-to-model VGICP
  int model_keyframes = 10;       // recent keyframes in the local model
  double keyframe_distance = 1.0; // m
  double keyframe_angle_deg = 10.0;
  int max_iterations = 32;
  // Constant-velocity prediction on real stamps: the last motion scaled by (this interval / the
  // last), at most max_interval_ratio; after a gap over max_gap s no motion is predicted.
  double max_interval_ratio = 10.0;
  double max_gap = 2.0;  // s
  // A registration matching fewer than retry_inlier_fraction of the points is retried (zero
  // motion, coarser voxels); if it still does and lands over retry_distance m from the prediction,
  // the frame is placed by the prediction. In our simulated drives good matches reach 0.89-0.96.
  double retry_distance = 1.0;
  double retry_inlier_fraction = 0.7;
  // Before any motion is known (the second frame, or after a gap of max_gap) the guess is standing
  // still, which a scan-to-scan cost on 1 m voxels confirms even at 27 m/s: the ground rings of
  // one sensor pose fall on themselves, and road-parallel structure does not object. The search
  // starts on voxels this large (m), where the rings blur into a plane (4 m is not enough on a
  // simulated highway with a per-beam elevation bias).
  double start_voxel_resolution = 8.0;
};

struct LocalMappingConfig {
  double th_max = 0.95;   // skip a frame whose overlap with the last keyframe exceeds this
  double th_min = 0.10;   // close the submap when overlap(first, last) falls below this
  int max_keyframes = 15; // N_max
  double voxel_resolution = 0.5;  // keyframe voxel maps for the in-submap factors
  double submap_downsample = 0.25;
  int max_submap_points = 60000;
  int factor_source_points = 0;  // > 0: keyframe points used as the source of in-submap factors (0: all)
  int max_iterations = 20;
  double relative_error_tol = 1e-4;  // LM stops once a step gains less than this fraction
};

struct GlobalMappingConfig {
  double th_min = 0.025;          // th_min_G: overlap needed for a matching-cost factor
  double voxel_resolution = 0.5;  // r_G (see README: 1 m tilts noisy maps)
  GlobalMode mode = GlobalMode::full;
  int window = 5;                 // sliding-window: connect to this many predecessors
  FactorSource factor = FactorSource::vgicp;
  int max_iterations = 10;        // per insertion (warm-started)
  double relative_error_tol = 1e-4;  // per insertion; the final optimization runs to 1e-6
  int final_iterations = 50;
  Relinearize relinearize = Relinearize::moved;
  // Norm of a factor's relative-pose change [rad, m] since its linearization. GLIM's iSAM2 uses
  // 0.1; on city's first 1500 frames, 0.02 / 0.01 / 0.005 gave t_rel 8.7 / 3.5 / 0.9 % above always.
  double relinearize_threshold = 0.01;
  // Per LM iteration of an insertion, at most this many moved factors are linearized anew (those
  // that moved most; 0: no limit), which bounds an insertion's cost where a revisit moves much of
  // the graph; the final optimization has no limit.
  int max_relinearizations = 0;
  LinearSolver linear_solver = LinearSolver::automatic;  // LM's sparse solve (graph/sparse_solver.hpp)
  // Points of a submap used as the source of its matching-cost factors and overlaps (an even
  // subsample; target voxel maps keep every point). The global graph's cost is linear in it.
  int factor_source_points = 20000;
};

// Explicit loops (paper Section III-C): ScanContext candidates between keyframes, GICP
// verification of the submap pair, an SE(3) constraint with a shifted Tukey kernel.
struct LoopConfig {
  bool enabled = true;
  ScanContextConfig scan_context;
  int exclude_recent = 5;                 // submaps before the current one that are not searched
  int num_candidates = 10;                // ring-key neighbours matched in full
  double max_descriptor_distance = 0.15;  // strict: a false loop costs more than a missed one
  double verification_downsample = 0.5;  // m, both submaps before GICP
  double inlier_distance = 0.3;          // m, after GICP
  // Strict, and the plane distance decides: in our simulated street grid (2 cm range noise), wrong
  // blocks rotated by 90 or 180 degrees aligned 0.60-0.74 of points at 3.3-6.6 cm, true revisits
  // 0.72-0.95 at 2.0-2.7 cm. Scale max_inlier_rmse with the sensor's noise.
  double min_inlier_fraction = 0.6;
  double max_inlier_rmse = 0.03;  // m, point-to-plane
  // Constant information of the constraint (sigmas), and the shifted Tukey kernel on its whitened
  // residual r: with the defaults the pull peaks at r = 1000 (10 m of translation), fades to zero
  // below r = 5 (5 cm: the matching-cost factors decide) and above r = 1995 (grossly wrong).
  double rotation_sigma_deg = 0.05;
  double translation_sigma = 0.01;  // m
  double tukey_width = 990025.0;    // w: zero weight where |r - offset| >= sqrt(w)
  double tukey_offset = 1000.0;
};

// Localization on a prior map (gcmap localize).
struct LocalizationConfig {
  // A frame tracks while at least this fraction of its points fall in voxels of the prior map
  // (at global.voxel_resolution); below it the frame is lost and global initialization runs.
  double min_overlap = 0.3;
  double submap_radius = 120.0;  // m: prior submaps whose origin is this close are candidates
  // ... of which those overlapping the frame most are matched, at most this many: cost grows with
  // each, accuracy hardly (a city map offers 30-49 within the radius).
  int max_submaps = 8;
  // Global initialization: a ScanContext candidate is accepted when GICP aligns at least this
  // fraction of the scan within loop.inlier_distance (a scan sees beyond one submap).
  double min_inlier_fraction = 0.3;
  // ... and their point-to-plane RMSE is at most this (m): one noisy scan against a submap, looser
  // than loop.max_inlier_rmse for two submaps. At 0.03 m, route 1 of the realistic `city` found
  // its place on route 0's map 200 frames later than at 0.07 m.
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
  // submaps meets its neighbour in its own session (the noise the sessions themselves show). An
  // absolute bound cannot serve both: on the small block, true places verify at 0.025 m (2 cm
  // range noise) and at 0.065-0.075 m (every realism on), another world's houses along the same
  // streets at 0.068 m among 2 cm-noise sessions.
  double min_inlier_fraction = 0.5;
  double max_rmse_ratio = 1.5;
  int max_iterations = 50;     // joint LM over all sessions
};

struct OutputConfig {
  double map_resolution = 0.1;
  bool pcd = false;
};

struct MappingConfig {
  PreprocessConfig preprocess;
  OdometryConfig odometry;
  LocalMappingConfig local;
  GlobalMappingConfig global;
  LoopConfig loop;
  LocalizationConfig localize;
  MergeConfig merge;
  OutputConfig output;

  // Throws Error("PATH: ...") naming the offending key.
  static MappingConfig load(const std::string& path);
  // The same on YAML text in memory (fuzzed); `name` stands for the path in messages.
  static MappingConfig parse(const std::string& yaml, const std::string& name);
  std::string to_yaml() const;
  void validate() const;

  // Every field by its "section.key" name, for front ends that set fields one by one (the Python
  // package); enums as their YAML names. Unknown keys and values of the wrong type throw Error
  // naming the key; set() does not validate (fields checked together may be set in any order).
  using Value = std::variant<bool, int, double, std::string>;
  static std::vector<std::string> keys();
  Value get(const std::string& key) const;
  void set(const std::string& key, const Value& value);
};

}  // namespace gcmap
