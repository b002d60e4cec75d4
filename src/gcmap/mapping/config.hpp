#pragma once
// One config struct per module with the paper's defaults (Koide et al., RA-L 2021), loadable
// from YAML. Every key is optional; an unknown key is an error naming it.
#include <string>

namespace gcmap {

struct PreprocessConfig {
  double min_range = 2.0;  // m: drops returns from the ego vehicle
  double max_range = 100.0;
  double downsample = 0.25;  // voxel size in m
  int num_neighbors = 10;    // covariance estimation
  bool kitti_vertical_correction = true;  // 0.22 deg intrinsic correction, KITTI layouts only
  bool remove_dynamic_labels = true;      // SemanticKITTI moving classes, when labels/ exists
};

struct OdometryConfig {
  double voxel_resolution = 1.0;  // scan-to-model VGICP
  int model_keyframes = 10;       // recent keyframes in the local model
  double keyframe_distance = 1.0; // m
  double keyframe_angle_deg = 10.0;
  int max_iterations = 32;
};

struct LocalMappingConfig {
  double th_max = 0.95;   // skip a frame whose overlap with the last keyframe exceeds this
  double th_min = 0.10;   // close the submap when overlap(first, last) falls below this
  int max_keyframes = 15; // N_max
  double voxel_resolution = 0.5;  // keyframe voxel maps for the in-submap factors
  double submap_downsample = 0.25;
  int max_submap_points = 60000;
  int max_iterations = 20;
};

struct GlobalMappingConfig {
  double th_min = 0.025;          // th_min_G: overlap needed for a matching-cost factor
  double voxel_resolution = 1.0;  // r_G
  std::string mode = "full";      // full | sliding-window
  int window = 5;                 // sliding-window: connect to this many predecessors
  std::string factor = "vgicp";   // vgicp | se3
  int max_iterations = 10;        // per insertion (warm-started)
  int final_iterations = 50;
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
  OutputConfig output;

  // Throws Error("PATH: ...") naming the offending key.
  static MappingConfig load(const std::string& path);
  std::string to_yaml() const;
  void validate() const;
};

}  // namespace gcmap
