#pragma once
// Local mapping (overlap-managed submaps, fully connected VGICP inside) and global mapping (a
// matching-cost factor to every overlapping past submap), paper Section III.
#include <memory>
#include <optional>
#include <vector>

#include "gcmap/graph/levenberg_marquardt.hpp"
#include "gcmap/mapping/config.hpp"
#include "gcmap/mapping/scan_context.hpp"

namespace gcmap {

struct Submap {
  int id = 0;
  std::vector<int> keyframes;                     // frame indices
  std::vector<Eigen::Isometry3d> T_submap_keyframe;  // fixed after the local optimization
  Eigen::Isometry3d T_odom = Eigen::Isometry3d::Identity();  // odometry pose of the submap origin
  std::shared_ptr<const PointCloud> cloud;        // merged, in the submap frame
  std::shared_ptr<const PointCloud> factor_source;  // subsample of cloud: source of its factors
  std::shared_ptr<const GaussianVoxelMap> voxels; // at global.voxel_resolution
};

struct FactorInfo {
  std::string type;  // matching_cost, odometry, se3, loop (explicit)
  int source = 0, target = 0;
  double overlap = 0.0;
  double error = 0.0;
  double weight = 1.0;  // robust-kernel weight at the final estimate (relative-pose factors)
};

// An explicit loop that passed or failed verification.
struct LoopRecord {
  int source = 0, target = 0;  // submaps
  double descriptor_distance = 0.0, inlier_fraction = 0.0, inlier_rmse = 0.0;
  bool accepted = false;
  Eigen::Isometry3d T_target_source = Eigen::Isometry3d::Identity();  // verified relative pose
};

struct TimingStats {
  std::vector<double> samples_ms;
  void add(double ms) { samples_ms.push_back(ms); }
  double mean() const;
  double stddev() const;
  double max() const;
};

struct MapperStats {
  TimingStats local_factors, local_optimization, global_factors, global_optimization;
  TimingStats loop_detection;     // ScanContext retrieval and matching, per submap (descriptors are made per keyframe)
  TimingStats loop_verification;  // GICP, per candidate
  struct PerSubmap {
    int num_submaps, num_factors;
    double global_optimization_ms;
    int global_iterations;  // LM iterations of this insertion, over all its optimize calls
  };
  std::vector<PerSubmap> per_submap;
  double final_optimization_ms = 0.0;  // also one sample of global_optimization
  int final_iterations = 0;
};

class Mapper {
 public:
  // backend: where factors are linearized and overlaps computed (default: the CPU).
  explicit Mapper(const MappingConfig& config, std::shared_ptr<LinearizationBackend> backend = nullptr);

  // Feeds a preprocessed frame (with covariances) and its odometry pose. Frames must come in order;
  // unusable frames (nullptr) are placed by odometry only.
  void add_frame(int frame, const std::shared_ptr<const PointCloud>& cloud, const Eigen::Isometry3d& T_odom);
  // Closes the open submap and runs the final global optimization.
  void finish();

  // World pose of every frame added (skipped frames via odometry from their anchor keyframe),
  // expressed so that the first frame is the identity.
  std::vector<Eigen::Isometry3d> trajectory() const;
  const std::vector<Submap>& submaps() const { return submaps_; }
  Eigen::Isometry3d submap_pose(int id) const { return values_.at(id); }
  std::vector<FactorInfo> factors() const;
  const MapperStats& stats() const { return stats_; }
  const std::vector<LoopRecord>& loops() const { return loops_; }
  size_t num_global_factors() const { return graph_.factors.size(); }
  // All submaps in the world frame, voxel-downsampled.
  PointCloud assemble_map(double resolution) const;

 private:
  struct Keyframe {
    int frame;
    Eigen::Isometry3d T_odom;
    std::shared_ptr<const PointCloud> cloud;
    std::shared_ptr<GaussianVoxelMap> voxels;  // local resolution, keyframe frame
    ScanContext descriptor;                    // when explicit loops are on
  };
  struct FrameRecord {
    int anchor = -1;  // keyframe frame index this frame is placed from
    Eigen::Isometry3d T_odom;
  };

  void close_submap();
  void insert_submap(Submap submap);
  // Matching-cost (or se3) factors from submap id to every past submap in [first, id) not in
  // `connected` whose overlap reaches th_min_G; returns how many were added.
  int connect_overlapping(int id, int first, std::vector<char>& connected);
  // The global graph without matching-cost factors between submaps more than loop.exclude_recent
  // apart (kept where a submap has nothing else).
  FactorGraph without_revisit_factors() const;
  // Searches the places of older submaps for the keyframes of submap id, verifies the best
  // candidate and adds a loop factor; true when one was added.
  bool close_explicit_loop(int id);

  MappingConfig config_;
  std::shared_ptr<LinearizationBackend> backend_;
  std::vector<Keyframe> open_;  // keyframes of the submap being built
  std::vector<Submap> submaps_;
  std::vector<FrameRecord> frames_;
  std::vector<std::pair<int, int>> keyframe_location_;  // per frame: (submap, index in submap) or (-1, -1)
  FactorGraph graph_;
  std::vector<FactorInfo> factor_info_;
  Values values_;
  LevenbergMarquardt lm_;
  MapperStats stats_;
  ScanContextDatabase places_;             // keyframe descriptors, in submap order
  std::vector<std::pair<int, int>> place_keyframe_;  // per place: (submap, index in submap)
  std::vector<size_t> submap_places_end_;  // per submap: places_ size once it was added
  std::vector<LoopRecord> loops_;
};

}  // namespace gcmap
