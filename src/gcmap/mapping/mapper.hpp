#pragma once
// The back end of the paper (Section III): local mapping, global mapping and explicit loops,
// composed; frames in, submaps and their optimized poses out.
#include <memory>
#include <optional>
#include <utility>
#include <vector>

#include "gcmap/graph/rotation_smoother.hpp"
#include "gcmap/mapping/global_mapper.hpp"
#include "gcmap/mapping/loop_detector.hpp"
#include "gcmap/mapping/submap_builder.hpp"

namespace gcmap {

// Whether the map of these submaps carries intensity: every cloud has it (empty ones agree with either).
bool have_intensities(const std::vector<Submap>& submaps);
// The submaps placed by T_out_submap (one each), voxel-downsampled, with a mean intensity per voxel
// when have_intensities; at most about block_points points (more only where one voxel column
// holds more) exist at once before downsampling.
PointCloud assemble_map(const std::vector<Submap>& submaps, const std::vector<Eigen::Isometry3d>& T_out_submap, double resolution,
                        size_t block_points = size_t{1} << 22);

// A GNSS fix in the local ENU frame of the run (io/gnss_io converts gnss.txt).
struct GnssPosition {
  double stamp = 0.0;
  Eigen::Vector3d p_enu = Eigen::Vector3d::Zero(), sigma = Eigen::Vector3d::Ones();
};

// What became of the fixes (at the current estimate).
struct GnssStats {
  size_t fixes = 0;
  size_t used = 0;            // a factor each
  size_t outside = 0;         // before the first scan or after the last
  size_t gaps = 0;            // between scans further apart than gnss.max_gap
  size_t waiting = 0;         // placed, but the fixes never spanned gnss.align_distance: no factor
  size_t rejected = 0;        // of used: residual beyond gnss.outlier_threshold sigmas
  size_t downweighted = 0;    // of used: beyond gnss.huber_width sigmas at the last linearization
  double rms_residual = 0.0;  // m, of the used fixes not rejected, horizontal and vertical together
  bool georeferenced = false;
};

// What the accelerometer did to the global graph.
struct GravityStats {
  size_t windows = 0;     // a GravityFactor each
  size_t downweighted = 0;  // beyond the Huber width at the last linearization
  bool levelled = false;  // the map's z is gravity's
  Eigen::Vector3d accel_bias = Eigen::Vector3d::Zero();  // m/s^2, IMU frame
  double rms_tilt_deg = 0.0;  // of the windows' up against the map's z, at the final poses
};

struct MapperStats {
  LocalMappingStats local;
  GlobalMappingStats global;
  LoopStats loop;
};

class Mapper {
 public:
  // backend: where factors are linearized and overlaps computed (default: the CPU).
  explicit Mapper(const MappingConfig& config, std::shared_ptr<LinearizationBackend> backend = nullptr);

  // Feeds a preprocessed frame (with covariances) and its odometry pose. Frames come in order,
  // numbered from 0; unusable frames (nullptr or too few points) are placed by odometry only.
  // shape: the cloud's keyframe_shape when made ahead.
  // stamp: s, needed only where GNSS fixes are to be placed. observed: the odometry's position of
  // the frame comes from a registration that sees every direction (not placed by a prediction, not
  // degenerate); gravity windows take only such frames, since they read gravity from positions.
  // gyro: the gyro's rotation since the previous frame (SubmapBuilder::add_frame).
  FrameStatus add_frame(int frame, const std::shared_ptr<const PointCloud>& cloud, const Eigen::Isometry3d& T_odom,
                        std::optional<KeyframeShape> shape = std::nullopt, double stamp = 0.0, bool observed = true,
                        const std::optional<GyroRotation>& gyro = std::nullopt);
  // GNSS fixes (stamps increasing) to place on the submaps as they close: each at the pose
  // interpolated between the frames around its stamp, the antenna at gnss.lever_arm_*.
  void set_gnss(std::vector<GnssPosition> fixes);
  bool georeferenced() const { return global_.georeferenced(); }
  GnssStats gnss_stats() const;
  // An IMU sample (on the IMU's clock, in its frame; imu.time_offset and T_lidar_imu apply), before
  // the frames it spans: each closing submap gets the accelerometer's gravity over the last
  // seconds of odometry (graph/gravity_window.hpp). Ignored unless imu.use and imu.level_map.
  void add_imu(const ImuSample& sample);
  // The IMU was found misplaced (its gyro disagrees): no more gravity or gyro rotations, and none
  // of what was taken.
  void drop_imu();
  bool levelled() const { return global_.levelled(); }
  GravityStats gravity_stats() const;
  // A frame's sweep deskewed again (SweepRevision), before the next frame is added: its odometry
  // pose, and its cloud when it is a keyframe. True when the cloud was taken; a frame whose submap
  // has closed keeps its place.
  bool revise_frame(int frame, const std::shared_ptr<const PointCloud>& cloud, const Eigen::Isometry3d& T_odom);
  // Closes the open submap and runs the final global optimization (at most max_final_iterations
  // when given; 0 skips it); on_iteration after each of its iterations.
  void finish(std::optional<int> max_final_iterations = std::nullopt, const IterationCallback& on_iteration = {});
  // Global optimizations of insertions end early once *stop is true; the final one is bounded by finish().
  void stop_on(const std::atomic<bool>* stop) { global_.stop_on(stop); }

  size_t num_frames() const { return frames_.size(); }
  // World pose of a frame (skipped frames via odometry from their anchor keyframe), expressed so
  // that frame 0 is the identity.
  Eigen::Isometry3d frame_pose(int frame) const;
  // Every frame's pose as frame_pose gives it, the rotations then smoothed with the gyro where
  // imu.smooth_rotations and the frames are noisier than the gyro (graph/rotation_smoother.hpp).
  std::vector<Eigen::Isometry3d> trajectory() const { return smoothed_trajectory().first; }
  RotationSmoothing rotation_smoothing() const { return smoothed_trajectory().second; }
  const std::vector<Submap>& submaps() const { return global_.submaps(); }
  // In the submap frame of submap 0 (see output_from_world()).
  const Eigen::Isometry3d& submap_pose(int id) const { return global_.pose(id); }
  const std::vector<GlobalFactor>& factors() const { return global_.factors(); }
  std::vector<FactorEvaluation> evaluate_factors() const { return global_.evaluate_factors(); }
  const std::vector<LoopRecord>& loops() const { return loops_.loops(); }
  MapperStats stats() const { return {local_.stats(), global_.stats(), loops_.stats()}; }
  const GlobalMappingStats& global_stats() const { return global_.stats(); }
  // The transform from the optimizer's world (submap 0's frame) to the output frame (frame 0).
  Eigen::Isometry3d output_from_world() const;
  // All submaps in the output frame (see gcmap::assemble_map).
  PointCloud assemble_map(double resolution, size_t block_points = size_t{1} << 22) const;

 private:
  struct FrameRecord {
    int anchor = -1;  // keyframe (frame index) this frame is placed from
    Eigen::Isometry3d T_odom;
    int submap = -1, index = -1;       // for keyframes of closed submaps: where the keyframe is
    bool observed = true;              // see add_frame
    std::optional<GyroRotation> gyro;  // since the previous frame
  };
  void insert(Submap submap);
  // The fixes from next_fix_ that can be placed now (their frames are in closed submaps, or in
  // `inserting`, which the global mapper does not hold yet).
  std::vector<GnssMeasurement> place_fixes(const Submap& inserting);
  // The gravity window over the last seconds of frames, in the frame of `inserting`.
  std::optional<GravityWindow> gravity_window(const Submap& inserting);
  // The gyro's rotation from the previous submap's origin to that of `inserting`, when it spans it.
  std::optional<GyroRotation> gyro_between_submaps(const Submap& inserting) const;
  // A frame's pose in its anchor's submap; nullopt while that submap is open.
  std::optional<std::pair<int, Eigen::Isometry3d>> in_submap(int frame, const Submap& inserting) const;
  Eigen::Isometry3d keyframe_world(int keyframe) const;
  Eigen::Isometry3d world_pose(int frame) const;
  std::pair<std::vector<Eigen::Isometry3d>, RotationSmoothing> smoothed_trajectory() const;

  MappingConfig config_;
  std::shared_ptr<LinearizationBackend> backend_;
  SubmapBuilder local_;
  LoopDetector loops_;
  GlobalMapper global_;
  std::vector<FrameRecord> frames_;
  std::vector<double> stamps_;
  std::vector<GnssPosition> fixes_;
  size_t next_fix_ = 0, fixes_outside_ = 0, fixes_gaps_ = 0;
  std::vector<ImuSample> imu_;  // LiDAR clock, IMU frame
  bool gravity_dropped_ = false;
};

}  // namespace gcmap
