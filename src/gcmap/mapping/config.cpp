#include "gcmap/mapping/config.hpp"

#include <yaml-cpp/yaml.h>

#include <charconv>
#include <cmath>
#include <cstdio>
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
const auto& enum_names() {
  if constexpr (std::is_same_v<E, GlobalMode>) return kGlobalModes;
  else if constexpr (std::is_same_v<E, FactorSource>) return kFactorSources;
  else if constexpr (std::is_same_v<E, Relinearize>) return kRelinearize;
  else return kLinearSolvers;
}

template <typename E>
E parse_config_enum(const std::string& text, const std::string& key) {
  return parse_enum(text, key, enum_names<E>());
}

// A key's documentation and valid range, beside its name in the table below. The range is
// inclusive and checked for numbers only; it allows what a real sensor or drive can need and no
// more, so that a typo (a unit off by 1e3, a sign) is an error naming the key, not a meaningless map.
struct KeyDoc {
  const char* unit;     // "-": none
  double min, max;      // numbers only
  const char* module;   // the folder of the code that reads it
  const char* meaning;  // one sentence or two, no '|' (it is a Markdown table cell)
};

// The one config table, keys in YAML order, split into a few functions by section to keep each short.
template <typename Config, typename Visitor>
void visit_preprocess(Config& c, Visitor& v) {
  v("preprocess", "min_range", c.preprocess.min_range,
    KeyDoc{"m", 0, 100, "odometry/", "Returns closer to the sensor than this are dropped: the ego vehicle and its mounts."});
  v("preprocess", "max_range", c.preprocess.max_range,
    KeyDoc{"m", 1, 1000, "odometry/",
           "Returns farther than this are dropped: far points are sparse and their angular noise grows with range. Must exceed "
           "min_range."});
  v("preprocess", "downsample", c.preprocess.downsample,
    KeyDoc{"m", 0.01, 100, "odometry/", "Voxel size of the downsampling of each scan before registration."});
  v("preprocess", "num_neighbors", c.preprocess.num_neighbors,
    KeyDoc{"-", 4, 100, "odometry/",
           "Nearest neighbours from which each point's covariance (its local surface shape) is estimated; twenty, so that "
           "far ground, whose rings lie further apart than the voxel grid, spans more than one ring."});
  v("preprocess", "plane_epsilon", c.preprocess.plane_epsilon,
    KeyDoc{"-", 1e-6, 1, "odometry/",
           "Each point's covariance is a plane: eigenvalues (this, 1, 1) along its normal and the surface. Smaller weighs the "
           "distance along the normal more against the distance along the surface: an ideal world of exact planes gains, but "
           "sparse scans, beams with an elevation bias and a straight road lose (1e-4 loses a highway's motion; "
           "docs/pipeline.md, \"Point covariances\")."});
  v("preprocess", "elevation_sigma_deg", c.preprocess.elevation_sigma_deg,
    KeyDoc{"deg", 0, 5, "odometry/",
           "Beam elevation uncertainty added to each point's covariance (range times this, in the beam's vertical plane), for a "
           "sensor whose beams have an elevation bias that puts far ground off its plane. 0: off."});
  v("preprocess", "elevation_calibration", c.preprocess.elevation_calibration,
    KeyDoc{"-", 0, 0, "mapping/",
           "A file of per-beam elevation offsets (written by `gcmap calibrate`) applied to every raw scan; empty: none."});
  v("preprocess", "kitti_vertical_correction", c.preprocess.kitti_vertical_correction,
    KeyDoc{"-", 0, 0, "mapping/",
           "The 0.22 deg intrinsic vertical correction of KITTI's HDL-64 scans; applied to KITTI layouts only."});
  v("preprocess", "remove_dynamic_labels", c.preprocess.remove_dynamic_labels,
    KeyDoc{"-", 0, 0, "mapping/",
           "Points of SemanticKITTI's moving classes are dropped, when the sequence has a labels/ folder."});
  v("preprocess", "deskew", c.preprocess.deskew,
    KeyDoc{"-", 0, 0, "odometry/",
           "Motion compensation of scans with per-point times, by the motion the odometry registers over the sweep (a velocity "
           "that changes linearly)."});
  v("preprocess", "redeskew", c.preprocess.redeskew,
    KeyDoc{"-", 0, 0, "odometry/",
           "Each sweep is deskewed again once the next one is registered, by the motion interpolated between the poses on both "
           "sides of it instead of extrapolated, for the map and the odometry's model."});
  v("preprocess", "deskew_from_azimuth", c.preprocess.deskew_from_azimuth,
    KeyDoc{"-", 0, 0, "mapping/",
           "Scans without per-point times from a spinning sensor get times from each point's azimuth: sweep_period times the "
           "fraction of the turn since sweep_start_deg."});
  v("preprocess", "sweep_period", c.preprocess.sweep_period,
    KeyDoc{"s", 0.01, 1, "mapping/", "Duration of one turn of the sensor, for deskew_from_azimuth."});
  v("preprocess", "sweep_start_deg", c.preprocess.sweep_start_deg,
    KeyDoc{"deg", -360, 360, "mapping/",
           "Azimuth at which a sweep starts, for deskew_from_azimuth; 0 is forward (+x), as in KITTI's HDL-64 files."});
  v("preprocess", "sweep_clockwise", c.preprocess.sweep_clockwise,
    KeyDoc{
        "-", 0, 0, "mapping/",
        "The sensor turns clockwise seen from above, for deskew_from_azimuth; false (counter-clockwise) as in KITTI's files."});
}

template <typename Config, typename Visitor>
void visit_calibration(Config& c, Visitor& v) {
  v("calibration", "estimate_elevation", c.calibration.estimate_elevation,
    KeyDoc{"-", 0, 0, "mapping/",
           "Without preprocess.elevation_calibration, `gcmap map` first estimates per-beam elevation offsets of a spinning "
           "sensor from the odometry of the first frames (levelled by walls) and maps every scan corrected by them."});
  v("calibration", "frames", c.calibration.frames,
    KeyDoc{"-", 10, 100000, "mapping/", "The first frames whose odometry the elevation estimate reads."});
  v("calibration", "every", c.calibration.every,
    KeyDoc{"-", 1, 1000, "mapping/", "Every n-th of those frames enters the estimate."});
  v("calibration", "passes", c.calibration.passes,
    KeyDoc{"-", 1, 10, "mapping/",
           "Odometry passes over those frames: the first places the scans as they came, each later one the scans corrected by "
           "the estimate before it, which gives back the part of the offsets that a drifting trajectory hides."});
  v("calibration", "min_offset_deg", c.calibration.min_offset_deg,
    KeyDoc{"deg", 0, 2, "mapping/",
           "Estimated offsets smaller than this are left out: a sensor without bias still gets hundredths of a degree from "
           "the estimate, and correcting by them costs accuracy; factory errors that bend far ground are about 0.1 deg or more."});
  v("calibration", "downsample", c.calibration.downsample,
    KeyDoc{"m", 0.01, 100, "mapping/",
           "Voxel size of the scans the passes' odometry registers (at least preprocess.downsample): coarser than the run's "
           "for speed; the scans that enter the estimate keep preprocess.downsample."});
  v("calibration", "min_travel", c.calibration.min_travel,
    KeyDoc{"m", 0, 100000, "mapping/",
           "The sensor must travel this far over those frames, or nothing is estimated: far ground is compared with the ground "
           "that other scans saw from close by."});
}

template <typename Config, typename Visitor>
void visit_odometry_local(Config& c, Visitor& v) {
  v("odometry", "voxel_resolution", c.odometry.voxel_resolution,
    KeyDoc{"m", 0.01, 100, "odometry/",
           "Voxel size of the scan-to-model VGICP registration of the odometry; not coarser: sparse scans turning fast (a "
           "Livox in hand) lose their motion on coarser models."});
  v("odometry", "model_keyframes", c.odometry.model_keyframes,
    KeyDoc{"-", 1, 100, "odometry/",
           "Recent keyframes whose points form the local model each scan is registered to; until it holds this many, every "
           "registered frame becomes one."});
  v("odometry", "keyframe_distance", c.odometry.keyframe_distance,
    KeyDoc{"m", 0, 100, "odometry/", "A frame becomes a keyframe of the model once it moved this far from the last keyframe."});
  v("odometry", "keyframe_angle_deg", c.odometry.keyframe_angle_deg,
    KeyDoc{"deg", 0, 180, "odometry/",
           "A frame becomes a keyframe of the model once it turned this much from the last keyframe."});
  v("odometry", "max_iterations", c.odometry.max_iterations,
    KeyDoc{"-", 1, 1000, "odometry/", "Gauss-Newton iterations of one scan-to-model registration, at most."});
  v("odometry", "max_interval_ratio", c.odometry.max_interval_ratio,
    KeyDoc{"-", 1, 1000, "odometry/",
           "The constant-velocity prediction scales the last motion by (this interval / the last one), at most by this factor, "
           "so that one odd stamp cannot throw the guess far."});
  v("odometry", "max_gap", c.odometry.max_gap,
    KeyDoc{"s", 0.01, 60, "odometry/",
           "After a gap between stamps longer than this, no motion is predicted: the guess is standing still."});
  v("odometry", "retry_distance", c.odometry.retry_distance,
    KeyDoc{"m", 0.01, 100, "odometry/",
           "A registration that matches too few points (retry_inlier_fraction) and lands farther than this from the prediction, "
           "or matches under half of what the last frames matched, is retried from zero motion on coarser voxels (2 m, or "
           "twice voxel_resolution); if it still does, the frame is placed by the prediction."});
  v("odometry", "retry_inlier_fraction", c.odometry.retry_inlier_fraction,
    KeyDoc{"-", 0, 1, "odometry/",
           "Fraction of a scan's points a registration must match to be trusted without a retry; good matches on clean data "
           "match far more than the default."});
  v("odometry", "start_voxel_resolution", c.odometry.start_voxel_resolution,
    KeyDoc{"m", 0.01, 100, "odometry/",
           "Before any motion is known (second frame, after a gap) the search starts from standing still on voxels this large, "
           "where the ground rings of one sensor pose blur into a plane instead of confirming the wrong guess. At least "
           "voxel_resolution."});
  v("local", "th_max", c.local.th_max,
    KeyDoc{"-", 0.01, 1, "mapping/",
           "A frame whose overlap with the last keyframe exceeds this is skipped (placed from that keyframe)."});
  v("local", "th_min", c.local.th_min,
    KeyDoc{"-", 0, 1, "mapping/",
           "A submap closes when the overlap of its first and last keyframes falls below this; below th_max."});
  v("local", "max_keyframes", c.local.max_keyframes,
    KeyDoc{"-", 2, 200, "mapping/", "Keyframes in a submap at most (N_max in the paper)."});
  v("local", "voxel_resolution", c.local.voxel_resolution,
    KeyDoc{"m", 0.01, 100, "mapping/", "Voxel size of the keyframe voxel maps of the in-submap matching-cost factors."});
  v("local", "submap_downsample", c.local.submap_downsample,
    KeyDoc{"m", 0.01, 100, "mapping/", "Voxel size of the downsampling of a submap's merged keyframes."});
  v("local", "max_submap_points", c.local.max_submap_points,
    KeyDoc{"-", 1000, 10000000, "mapping/",
           "Points of a submap cloud at most (an even subsample beyond it), which bounds memory per submap."});
  v("local", "factor_source_points", c.local.factor_source_points,
    KeyDoc{"-", 0, 10000000, "mapping/",
           "Keyframe points used as the source of the in-submap factors (an even subsample); 0: all, else at least 1000."});
  v("local", "max_iterations", c.local.max_iterations,
    KeyDoc{"-", 1, 1000, "mapping/", "Levenberg-Marquardt iterations of a submap's keyframe optimization, at most."});
  v("local", "relative_error_tol", c.local.relative_error_tol,
    KeyDoc{"-", 0, 1, "mapping/", "The submap's optimization stops once a step lowers the error by less than this fraction."});
  v("local", "robust_width", c.local.robust_width,
    KeyDoc{"-", 0, 100, "mapping/",
           "> 0: each point of an in-submap matching cost counts c^2 / (c^2 + m^2) times, m its Mahalanobis distance to its "
           "voxel (Cauchy's cost): points many sigmas off (a thin object seen from its other side, a voxel holding two "
           "surfaces) pull less. 0: every point counts fully."});
  v("local", "gyro_weight", c.local.gyro_weight,
    KeyDoc{"-", 0, 1e6, "mapping/",
           "With an IMU, the gyro's rotation between consecutive keyframes is a factor of their submap, weighted this many times "
           "what the gyro's noise (imu.gyro_noise) gives it: the matching costs count every point as independent and outweigh "
           "it otherwise, while they turn sparse sweeps against each other by tenths of a degree. 0: no such factor."});
  v("local", "inertial_translation_sigma", c.local.inertial_translation_sigma,
    KeyDoc{"m", 0, 100, "mapping/",
           "With the LiDAR-inertial state (imu.inertial_odometry), its translation between consecutive keyframes joins the "
           "gyro's rotation in their factor, at this sigma per axis: it holds keyframes along what their matching costs hardly "
           "see (a corridor) and against sweeps a fast turn distorted, and counts little elsewhere. 0 (or local.gyro_weight "
           "0): no such translation."});
}

template <typename Config, typename Visitor>
void visit_global(Config& c, Visitor& v) {
  v("global", "th_min", c.global.th_min,
    KeyDoc{"-", 0, 1, "mapping/", "Overlap two submaps need for a matching-cost factor between them (th_min_G in the paper)."});
  v("global", "voxel_resolution", c.global.voxel_resolution,
    KeyDoc{
        "m", 0.01, 100, "mapping/",
        "Voxel size of the submap voxel maps of the global matching-cost factors (r_G); coarse voxels tilt maps of noisy data."});
  v("global", "mode", c.global.mode,
    KeyDoc{"-", 0, 0, "mapping/",
           "full: a factor to every overlapping past submap (the paper); sliding-window: only to the last `window` submaps."});
  v("global", "window", c.global.window,
    KeyDoc{"-", 1, 1000, "mapping/", "Predecessors each submap is connected to in the sliding-window mode."});
  v("global", "factor", c.global.factor,
    KeyDoc{"-", 0, 0, "mapping/",
           "vgicp: matching-cost factors (the paper); se3: relative poses from scan matching (its ablation)."});
  v("global", "max_iterations", c.global.max_iterations,
    KeyDoc{"-", 1, 1000, "mapping/", "Levenberg-Marquardt iterations per submap insertion (warm-started), at most."});
  v("global", "relative_error_tol", c.global.relative_error_tol,
    KeyDoc{"-", 0, 1, "mapping/",
           "An insertion's optimization stops once a step lowers the error by less than this fraction; the final one runs to "
           "1e-6."});
  v("global", "final_iterations", c.global.final_iterations,
    KeyDoc{"-", 1, 1000, "mapping/", "Levenberg-Marquardt iterations of the final optimization after the last submap, at most."});
  v("global", "relinearize", c.global.relinearize,
    KeyDoc{"-", 0, 0, "mapping/",
           "always: every factor at every iteration (the paper); moved: only factors whose poses moved more than "
           "relinearize_threshold since their last linearization (much faster on long drives)."});
  v("global", "relinearize_threshold", c.global.relinearize_threshold,
    KeyDoc{"-", 0, 10, "mapping/",
           "Norm of a factor's relative-pose change (rad and m together) since its linearization above which it is linearized "
           "anew. Lower stays closer to the result of always, at more cost; GLIM's iSAM2 uses 0.1."});
  v("global", "max_relinearizations", c.global.max_relinearizations,
    KeyDoc{"-", 0, 10000000, "mapping/",
           "Moved factors linearized anew per iteration of an insertion at most (those that moved most), which bounds the cost "
           "of an insertion where a revisit moves much of the graph; 0: no limit. The final optimization has none."});
  v("global", "linear_solver", c.global.linear_solver,
    KeyDoc{"-", 0, 0, "graph/",
           "Sparse solver of each Levenberg-Marquardt step: eigen, cholmod (when built with SuiteSparse) or auto."});
  v("global", "max_new_factors", c.global.max_new_factors,
    KeyDoc{"-", 0, 100000, "mapping/",
           "Matching-cost factors a new submap gets at most: to its predecessor and the past submaps it overlaps most; 0: "
           "to every one above th_min."});
  v("global", "min_conditioning", c.global.min_conditioning,
    KeyDoc{"-", 0, 1, "mapping/",
           "A matching-cost factor whose translation is held in one direction by less than this fraction of the best (smallest "
           "over largest eigenvalue of its Hessian's translation block, rotation marginalized: a tunnel, a corridor) is blind "
           "along it: what such a cost tells along a tunnel is noise, and a graph of them moved tunnels' submaps by metres; "
           "there the submaps stay where the odometry put them. 0: off."});
  v("global", "robust_width", c.global.robust_width,
    KeyDoc{"-", 0, 100, "mapping/",
           "> 0: each point of a global matching cost counts c^2 / (c^2 + m^2), m its Mahalanobis distance to its voxel "
           "(Cauchy's cost; see local.robust_width). 0: every point counts fully."});
  v("global", "factor_source_points", c.global.factor_source_points,
    KeyDoc{"-", 1000, 10000000, "mapping/",
           "Points of a submap used as the source of its matching-cost factors and overlaps (an even subsample; the target voxel "
           "maps keep every point). The global graph's cost is linear in it."});
}

template <typename Config, typename Visitor>
void visit_loop(Config& c, Visitor& v) {
  v("loop", "enabled", c.loop.enabled,
    KeyDoc{"-", 0, 0, "mapping/", "Explicit loop closures: ScanContext candidates, GICP verification, an SE(3) constraint."});
  v("loop", "rings", c.loop.scan_context.rings,
    KeyDoc{"-", 1, 200, "loop/", "Radial bins of the ScanContext descriptor of a keyframe."});
  v("loop", "sectors", c.loop.scan_context.sectors,
    KeyDoc{"-", 2, 360, "loop/",
           "Azimuth bins of the ScanContext descriptor; they also set the resolution of the yaw it gives."});
  v("loop", "max_radius", c.loop.scan_context.max_radius,
    KeyDoc{"m", 1, 1000, "loop/", "Points farther from the sensor than this are left out of the descriptor."});
  v("loop", "lidar_height", c.loop.scan_context.lidar_height,
    KeyDoc{"m", -10, 50, "loop/",
           "Height of the sensor above the ground, added to each point's z so that ground returns count as occupied cells."});
  v("loop", "exclude_recent", c.loop.exclude_recent,
    KeyDoc{"-", 1, 1000, "mapping/",
           "Submaps just before the current one that are not searched for loops: the matching-cost factors already join them."});
  v("loop", "num_candidates", c.loop.num_candidates,
    KeyDoc{"-", 1, 100, "loop/", "Nearest places by ring key whose descriptors are matched in full, per query."});
  v("loop", "max_descriptor_distance", c.loop.max_descriptor_distance,
    KeyDoc{"-", 0.001, 1, "mapping/",
           "Descriptor (cosine) distance a loop candidate may have at most; strict because a false loop costs more than a "
           "missed one."});
  v("loop", "verification_downsample", c.loop.verification_downsample,
    KeyDoc{"m", 0.01, 100, "loop/", "Voxel size both submaps are downsampled to before the GICP verification of a candidate."});
  v("loop", "inlier_distance", c.loop.inlier_distance,
    KeyDoc{"m", 0.01, 100, "loop/",
           "A point is an inlier of the verification when a point of the other submap lies this close after GICP."});
  v("loop", "min_inlier_fraction", c.loop.min_inlier_fraction,
    KeyDoc{"-", 0.01, 1, "loop/",
           "Fraction of the source submap's points that must be inliers for a loop to be accepted; wrong places in a regular "
           "street grid align many points too, so max_inlier_rmse decides."});
  v("loop", "max_inlier_rmse", c.loop.max_inlier_rmse,
    KeyDoc{"m", 0.001, 10, "loop/",
           "Point-to-plane RMSE of the inliers a loop may have at most: true revisits align at about the range noise, wrong "
           "places clearly above it. Scale it with the sensor's noise, and with preprocess.num_neighbors (the planes the "
           "distances are taken to)."});
  v("loop", "min_conditioning", c.loop.min_conditioning,
    KeyDoc{"-", 0, 1, "loop/",
           "Smallest over largest eigenvalue of the verification's translation information (rotation marginalized) a loop "
           "needs: a featureless tunnel aligns as well 100 m further on, and only along its axis is it free."});
  v("loop", "rotation_sigma_deg", c.loop.rotation_sigma_deg,
    KeyDoc{"deg", 0.0001, 180, "loop/", "Rotation sigma of the loop constraint's constant information."});
  v("loop", "translation_sigma", c.loop.translation_sigma,
    KeyDoc{"m", 0.0001, 100, "loop/", "Translation sigma of the loop constraint's constant information."});
  v("loop", "tukey_width", c.loop.tukey_width,
    KeyDoc{"-", 1e-6, 1e12, "loop/",
           "Width w of the shifted Tukey kernel on the constraint's whitened residual r: zero weight where r is sqrt(w) "
           "or more from tukey_offset. With the defaults the pull fades below r = 5 (the matching-cost factors decide) and above "
           "r = 1995 "
           "(grossly wrong loops)."});
  v("loop", "tukey_offset", c.loop.tukey_offset,
    KeyDoc{"-", 0, 1e6, "loop/",
           "Offset of the shifted Tukey kernel: the whitened residual at which the loop pulls most (with the default sigmas, "
           "10 m of translation)."});
}

template <typename Config, typename Visitor>
void visit_imu(Config& c, Visitor& v) {
  v("imu", "use", c.imu.use,
    KeyDoc{"-", 0, 0, "odometry/",
           "Use the IMU the input carries (imu.txt beside the scans, --imu, a bag's sensor_msgs/Imu topic): its gyro deskews "
           "each sweep and predicts its rotation, its accelerometer levels the map (level_map). false: as without one (also "
           "--no-imu)."});
  v("imu", "x", c.imu.x, KeyDoc{"m", -10, 10, "odometry/", "The IMU's origin in the LiDAR frame (T_lidar_imu): x."});
  v("imu", "y", c.imu.y, KeyDoc{"m", -10, 10, "odometry/", "The IMU's origin in the LiDAR frame: y."});
  v("imu", "z", c.imu.z, KeyDoc{"m", -10, 10, "odometry/", "The IMU's origin in the LiDAR frame: z."});
  v("imu", "roll_deg", c.imu.roll_deg,
    KeyDoc{"deg", -180, 180, "odometry/",
           "The IMU frame's rotation in the LiDAR frame (T_lidar_imu): roll, pitch, yaw about the LiDAR's fixed x, y, z axes, in "
           "that order."});
  v("imu", "pitch_deg", c.imu.pitch_deg,
    KeyDoc{"deg", -90, 90, "odometry/", "The IMU frame's rotation in the LiDAR frame: pitch (see roll_deg)."});
  v("imu", "yaw_deg", c.imu.yaw_deg,
    KeyDoc{"deg", -180, 180, "odometry/", "The IMU frame's rotation in the LiDAR frame: yaw (see roll_deg)."});
  v("imu", "time_offset", c.imu.time_offset,
    KeyDoc{"s", -1, 1, "odometry/", "An IMU stamp minus the LiDAR's stamp of the same instant (the IMU clock's lead)."});
  v("imu", "gyro_noise", c.imu.noise.gyro_noise,
    KeyDoc{"rad/s/sqrt(Hz)", 0, 1, "odometry/",
           "Gyro white noise density (default: a MEMS IMU built into a LiDAR, inflated for vibration). A sweep takes the gyro's "
           "change of the turn rate only as far as it stands above this noise, or above the density measured against the "
           "registered rotations where that is under 0.8 of it (after 5 s of sweeps; stats.json "
           "imu.deskew_gyro_noise_rad_s_sqrt_hz)."});
  v("imu", "accel_noise", c.imu.noise.accel_noise,
    KeyDoc{"m/s^2/sqrt(Hz)", 0, 10, "odometry/",
           "Accelerometer white noise density as the estimation takes it: five times a MEMS IMU's built into a LiDAR, so that "
           "the LiDAR-inertial state's velocity keeps listening to the registration (a walk diverged with the sensor's 0.02); "
           "also part of the weight of each gravity window (level_map)."});
  v("imu", "inertial_odometry", c.imu.inertial_odometry,
    KeyDoc{"-", 0, 0, "odometry/",
           "Pose, velocity and biases estimated at every sweep from the IMU and the registration (a two-sweep fixed-lag "
           "smoother), whose pose the sweep takes: the IMU predicts where each sweep starts, translation included, and holds "
           "what the registration cannot see or place (a tunnel, a fast turn). false: the sweep's pose is its registration's, "
           "the gyro predicts the rotation, the last motion the translation."});
  v("imu", "smooth_rotations", c.imu.smooth_rotations,
    KeyDoc{"-", 0, 0, "mapping/",
           "The trajectory's rotations are refined with the gyro's rotations between consecutive frames, where they disagree "
           "with them more than the gyro's noise explains (a sparse sensor in hand: its registrations turn the frames by tenths "
           "of a degree). Positions and the map stay; stats.json imu.rotation_smoothing says what was measured."});
  v("imu", "level_map", c.imu.level_map,
    KeyDoc{"-", 0, 0, "mapping/",
           "The accelerometer's gravity, measured over every submap's last 4 s of odometry, holds the global graph level: the "
           "map's z is gravity's, and the accelerometer's bias is estimated with it. false: the map stays in the first scan's "
           "frame."});
}

template <typename Config, typename Visitor>
void visit_gnss(Config& c, Visitor& v) {
  v("gnss", "lever_arm_x", c.gnss.lever_arm_x,
    KeyDoc{"m", -100, 100, "mapping/", "The GNSS antenna in the LiDAR (sensor) frame: x."});
  v("gnss", "lever_arm_y", c.gnss.lever_arm_y,
    KeyDoc{"m", -100, 100, "mapping/", "The GNSS antenna in the LiDAR (sensor) frame: y."});
  v("gnss", "lever_arm_z", c.gnss.lever_arm_z,
    KeyDoc{"m", -100, 100, "mapping/", "The GNSS antenna in the LiDAR (sensor) frame: z."});
  v("gnss", "huber_width", c.gnss.huber_width,
    KeyDoc{"-", 0.1, 1000, "mapping/",
           "Huber kernel of the GNSS position factors, in sigmas of the fix: beyond it a fix pulls with a constant force, so "
           "a multipath outlier of metres moves the map little."});
  v("gnss", "align_distance", c.gnss.align_distance,
    KeyDoc{"m", 1, 100000, "mapping/",
           "The fixes must span this far horizontally (and ten times their horizontal sigma), and spread across their main "
           "direction by a sixth of this distance (RMS, and three sigmas: a rotation about a straight track is invisible to "
           "positions), before the map is "
           "turned and moved onto them (yaw and translation); until then the first submap holds the gauge."});
  v("gnss", "max_gap", c.gnss.max_gap,
    KeyDoc{"s", 0.01, 60, "mapping/",
           "A fix is placed between the two scans around its stamp; where they are further apart than this it is skipped."});
  v("gnss", "outlier_threshold", c.gnss.outlier_threshold,
    KeyDoc{"-", 1, 1e6, "mapping/",
           "A fix whose residual at the final estimate exceeds this many of its sigmas is counted as rejected (stats.json)."});
}

template <typename Config, typename Visitor>
void visit_localize_merge_output(Config& c, Visitor& v) {
  v("localize", "min_overlap", c.localize.min_overlap,
    KeyDoc{"-", 0.01, 1, "session/",
           "A frame tracks while at least this fraction of its points fall in voxels of the prior map (at "
           "global.voxel_resolution); below it the frame is lost and global initialization runs."});
  v("localize", "submap_radius", c.localize.submap_radius,
    KeyDoc{"m", 1, 10000, "session/", "Prior submaps whose origin is this close to the frame are candidates for matching."});
  v("localize", "max_submaps", c.localize.max_submaps,
    KeyDoc{"-", 1, 100, "session/",
           "Of those, the ones overlapping the frame most are matched, at most this many: the cost grows with each, the "
           "accuracy hardly."});
  v("localize", "min_inlier_fraction", c.localize.min_inlier_fraction,
    KeyDoc{"-", 0.01, 1, "session/",
           "Global initialization accepts a ScanContext candidate when GICP aligns at least this fraction of the scan within "
           "loop.inlier_distance; lower than for loops, since a scan sees beyond one submap."});
  v("localize", "max_inlier_rmse", c.localize.max_inlier_rmse,
    KeyDoc{"m", 0.001, 10, "session/",
           "Global initialization also needs the point-to-plane RMSE of those inliers to be at most this: one noisy scan "
           "against a submap, looser than loop.max_inlier_rmse for two submaps (a strict bound finds the place much later)."});
  v("localize", "relocalize_every", c.localize.relocalize_every,
    KeyDoc{"-", 1, 10000, "session/", "Frames between global initialization attempts while lost."});
  v("merge", "max_descriptor_distance", c.merge.max_descriptor_distance,
    KeyDoc{"-", 0.001, 1, "session/",
           "Descriptor distance of a place between sessions at most; looser than loop.max_descriptor_distance since another "
           "session passes a place in another lane or direction (the GICP verification rejects wrong ones)."});
  v("merge", "max_verifications", c.merge.max_verifications,
    KeyDoc{"-", 1, 10000, "session/",
           "GICP verifications (distinct submap pairs, best ScanContext candidates first) per session to place, at most."});
  v("merge", "min_inlier_fraction", c.merge.min_inlier_fraction,
    KeyDoc{"-", 0.01, 1, "session/",
           "A place between sessions is accepted when GICP aligns at least this fraction of the source submap within "
           "loop.inlier_distance, at an RMSE that max_rmse_ratio allows."});
  v("merge", "max_rmse_ratio", c.merge.max_rmse_ratio,
    KeyDoc{"-", 0.01, 100, "session/",
           "A place between sessions may have a point-to-plane RMSE of at most loop.max_inlier_rmse, or of at most this times "
           "the RMSE at which each of "
           "the two submaps meets its neighbour in its own session: no absolute bound suits both clean and noisy sessions."});
  v("merge", "max_iterations", c.merge.max_iterations,
    KeyDoc{"-", 1, 1000, "session/", "Levenberg-Marquardt iterations of the joint optimization of all sessions, at most."});
  visit_gnss(c, v);
  visit_imu(c, v);
  v("output", "map_resolution", c.output.map_resolution,
    KeyDoc{"m", 0.01, 100, "apps/gcmap/", "Voxel size of the written map (map.ply, map.pcd)."});
  v("output", "pcd", c.output.pcd, KeyDoc{"-", 0, 0, "apps/gcmap/", "Also write the map as map.pcd, beside map.ply."});
}

template <typename Config, typename Visitor>
void visit_quality(Config& c, Visitor& v) {
  v("quality", "degenerate_conditioning", c.quality.degenerate_conditioning,
    KeyDoc{"-", 0, 1, "mapping/",
           "quality.json flags a frame degenerate when the translation conditioning of its registration (smallest over "
           "largest eigenvalue of the translation information) is below this."});
  v("quality", "inconsistent_factor", c.quality.inconsistent_factor,
    KeyDoc{"-", 1, 1000, "mapping/",
           "Two overlapping submaps disagree when registering one onto the other moves it more than this times their noise: "
           "what their keyframes disagree among themselves, averaged over each submap's keyframes (for submaps loaded from a "
           "session: the median shift of consecutive submaps)."});
  v("quality", "min_shift", c.quality.min_shift,
    KeyDoc{"m", 0, 100, "mapping/", "... and by at least this: below it a disagreement does not matter for a map."});
  v("quality", "pair_radius", c.quality.pair_radius,
    KeyDoc{"m", 0.1, 10000, "mapping/", "Submaps whose origins are this close are registered onto each other and compared."});
  v("quality", "min_pair_inliers", c.quality.min_pair_inliers,
    KeyDoc{"-", 0.01, 1, "mapping/",
           "A compared pair counts only when at least this fraction of the source submap's points meet the other's voxels "
           "after registration: less overlap says nothing about consistency."});
  v("quality", "coarse_resolution", c.quality.coarse_resolution,
    KeyDoc{"m", 0.1, 100, "mapping/",
           "A pair that overlaps too little at its final poses (a revisit that drifted apart) is registered first at voxels "
           "of this size, then at global.voxel_resolution; a drift up to about this much is found."});
  v("quality", "stamp_gap_factor", c.quality.stamp_gap_factor,
    KeyDoc{"-", 1, 1000, "mapping/",
           "A stamp interval over this times the median one (or a stamp not increasing) is reported as an anomaly."});
}

// Visits every (section, key, field, doc) once, for loading, dumping, checking and documenting.
template <typename Config, typename Visitor>
void visit(Config& c, Visitor&& v) {
  visit_preprocess(c, v);
  visit_calibration(c, v);
  visit_odometry_local(c, v);
  visit_global(c, v);
  visit_loop(c, v);
  visit_localize_merge_output(c, v);
  visit_quality(c, v);
}

// Every section and key must be a known plain name.
void check_known_keys(const YAML::Node& root, const std::string& path) {
  std::map<std::string, std::map<std::string, bool>> known;
  MappingConfig defaults;
  visit(defaults, [&](const char* s, const char* k, auto&, const KeyDoc&) { known[s][k] = true; });
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
  } catch (const YAML::Exception& e) { throw Error(path + ": YAML syntax error at line " + std::to_string(e.mark.line + 1)); }
  MappingConfig c;
  if (root.IsNull()) return c;
  if (!root.IsMap()) throw Error(path + ": expected a mapping of sections");
  check_known_keys(root, path);
  const YAML::Node& croot = root;
  visit(c, [&](const char* s, const char* k, auto& field, const KeyDoc&) {
    const YAML::Node section = croot[s];
    if (!section.IsDefined() || !section.IsMap()) return;
    const YAML::Node node = section[k];
    if (!node.IsDefined()) return;
    using T = std::decay_t<decltype(field)>;
    const std::string key = std::string(s) + "." + k;
    try {
      if constexpr (std::is_enum_v<T>) field = parse_config_enum<T>(node.as<std::string>(), key);
      else field = node.as<T>();
    } catch (const Error& e) { throw Error(path + ": " + e.what()); } catch (const YAML::Exception&) {
      throw Error(path + ": key '" + key + "' has an unreadable value");
    }
    if constexpr (std::is_floating_point_v<T>)
      if (!std::isfinite(field)) throw Error(path + ": key '" + key + "' must be a finite number");
  });
  try {
    c.validate();
  } catch (const Error& e) { throw Error(path + ": " + e.what()); }
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

// A field as its YAML text (also its default in the documentation).
template <typename T>
std::string yaml_value(const T& field) {
  if constexpr (std::is_same_v<T, bool>) return field ? "true" : "false";
  else if constexpr (std::is_enum_v<T>) return to_string(field);
  else if constexpr (std::is_floating_point_v<T>) return format_double(field);
  else if constexpr (std::is_same_v<T, std::string>) return double_quoted(field);
  else return std::to_string(field);
}

// Numbers outside the key's range; NaN is outside every range.
template <typename T>
void check_range(const char* s, const char* k, const T& field, const KeyDoc& doc) {
  if constexpr (std::is_arithmetic_v<T> && !std::is_same_v<T, bool>) {
    if (field >= doc.min && field <= doc.max) return;
    throw Error(std::string(s) + "." + k + " must be in [" + yaml_value(static_cast<T>(doc.min)) + ", " +
                yaml_value(static_cast<T>(doc.max)) + "]" + (doc.unit == std::string("-") ? "" : std::string(" ") + doc.unit) +
                ", got " + yaml_value(field));
  }
}

}  // namespace

std::string MappingConfig::to_yaml() const {
  std::ostringstream out;
  std::string current;
  visit(*this, [&](const char* s, const char* k, const auto& field, const KeyDoc&) {
    if (current != s) {
      out << s << ":\n";
      current = s;
    }
    out << "  " << k << ": " << yaml_value(field) << "\n";
  });
  return out.str();
}

// Each key's range comes from the table; what is left here relates keys to each other or to the build.
void MappingConfig::validate() const {
  visit(*this, [](const char* s, const char* k, const auto& field, const KeyDoc& doc) { check_range(s, k, field, doc); });
  auto need = [](bool ok, const std::string& what) {
    if (!ok) throw Error(what);
  };
  need(preprocess.max_range > preprocess.min_range, "preprocess.max_range must exceed preprocess.min_range");
  need(odometry.start_voxel_resolution >= odometry.voxel_resolution,
       "odometry.start_voxel_resolution must be at least odometry.voxel_resolution");
  need(local.th_min < local.th_max, "local.th_min must be below local.th_max");
  need(local.factor_source_points == 0 || local.factor_source_points >= 1000, "local.factor_source_points must be 0 or >= 1000");
  need(global.linear_solver != LinearSolver::cholmod || cholmod_available(),
       "global.linear_solver is cholmod, but this build has no CHOLMOD (SuiteSparse)");
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
  visit(defaults, [&](const char* s, const char* k, const auto&, const KeyDoc&) { out.push_back(std::string(s) + "." + k); });
  return out;
}

MappingConfig::Value MappingConfig::get(const std::string& key) const {
  std::optional<Value> out;
  visit(*this, [&](const char* s, const char* k, const auto& field, const KeyDoc&) {
    if (out || key != std::string(s) + "." + k) return;
    if constexpr (std::is_enum_v<std::decay_t<decltype(field)>>) out = std::string(to_string(field));
    else out = Value(field);
  });
  if (!out) throw Error("unknown key '" + key + "'");
  return *out;
}

void MappingConfig::set(const std::string& key, const Value& value) {
  bool found = false;
  visit(*this, [&](const char* s, const char* k, auto& field, const KeyDoc&) {
    if (found || key != std::string(s) + "." + k) return;
    found = true;
    field = convert<std::decay_t<decltype(field)>>(value, key);
  });
  if (!found) throw Error("unknown key '" + key + "'");
}

namespace {

template <typename T>
const char* type_name() {
  if constexpr (std::is_same_v<T, bool>) return "bool";
  else if constexpr (std::is_enum_v<T>) return "name";
  else if constexpr (std::is_floating_point_v<T>) return "number";
  else if constexpr (std::is_same_v<T, std::string>) return "path";
  else return "integer";
}

template <typename T>
std::string range_text(const KeyDoc& doc) {
  if constexpr (std::is_same_v<T, bool>) return "true, false";
  else if constexpr (std::is_same_v<T, std::string>) return "a file, or empty";
  else if constexpr (std::is_enum_v<T>) {
    std::string out;
    for (const auto& [value, name] : enum_names<T>()) out += (out.empty() ? "" : ", ") + std::string(name);
    return out;
  } else return "[" + yaml_value(static_cast<T>(doc.min)) + ", " + yaml_value(static_cast<T>(doc.max)) + "]";
}

// Words of `text` on lines of at most `width` characters, each after `indent`.
std::string wrapped(const std::string& text, const std::string& indent, size_t width) {
  std::istringstream words(text);
  std::string out, line, word;
  while (words >> word) {
    if (!line.empty() && line.size() + 1 + word.size() > width) {
      out += indent + line + "\n";
      line.clear();
    }
    line += (line.empty() ? "" : " ") + word;
  }
  return out + indent + line + "\n";
}

}  // namespace

std::vector<ConfigKeyDoc> MappingConfig::documentation() {
  std::vector<ConfigKeyDoc> out;
  const MappingConfig defaults;
  visit(defaults, [&](const char* s, const char* k, const auto& field, const KeyDoc& doc) {
    using T = std::decay_t<decltype(field)>;
    out.push_back({s, k, type_name<T>(), yaml_value(field), doc.unit, range_text<T>(doc), doc.module, doc.meaning});
  });
  return out;
}

std::string config_reference_text() {
  std::ostringstream out;
  char line[256];
  std::snprintf(line, sizeof(line), "%-40s %-8s %-10s %-5s %-24s %s\n", "KEY", "TYPE", "DEFAULT", "UNIT", "RANGE", "MODULE");
  out << line;
  for (const ConfigKeyDoc& d : MappingConfig::documentation()) {
    std::snprintf(line, sizeof(line), "%-40s %-8s %-10s %-5s %-24s %s\n", (d.section + "." + d.key).c_str(), d.type.c_str(),
                  d.default_value.c_str(), d.unit.c_str(), d.range.c_str(), d.module.c_str());
    out << line << wrapped(d.meaning, "    ", 96);
  }
  return out.str();
}

std::string config_reference_markdown() {
  std::ostringstream out;
  out << "<!-- Generated from the config table (src/gcmap/mapping/config.cpp) by `gcmap config --describe --markdown > "
         "docs/config.md`; do not edit by hand (a unit test compares). -->\n"
      << "# Configuration\n\n"
      << "Every key of the YAML file that `--config` takes (`gcmap map`, `localize`, `merge`, `calibrate`, `config`). Every key "
         "is "
         "optional and keeps its default when left out; an unknown key, a value of the wrong type or one outside its range is an "
         "error naming the key and the file. `gcmap config` prints the defaults as YAML, `gcmap config --config FILE` checks a "
         "file, and `gcmap config --describe` prints this table. Ranges are inclusive; the module is the source folder "
         "(src/gcmap/...) of the code that reads the key.\n";
  std::string section;
  for (const ConfigKeyDoc& d : MappingConfig::documentation()) {
    if (d.section != section) {
      section = d.section;
      out << "\n## " << section
          << "\n\n| key | type | default | unit | range | module | meaning |\n|---|---|---|---|---|---|---|\n";
    }
    out << "| `" << d.key << "` | " << d.type << " | `" << d.default_value << "` | " << d.unit << " | " << d.range << " | "
        << d.module << " | " << d.meaning << " |\n";
  }
  return out.str();
}

}  // namespace gcmap
