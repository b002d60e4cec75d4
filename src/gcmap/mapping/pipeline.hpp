#pragma once
// The whole mapping system as a library, scan by scan: preprocessing (corrections, label-based
// removal, downsampling, covariances, motion compensation), odometry or a given initial
// trajectory, and the Mapper. The CLI, the Python package and any other front end drive this.
#include <atomic>
#include <functional>
#include <memory>
#include <optional>

#include "gcmap/calibration/elevation_calibration.hpp"
#include "gcmap/core/scan_source.hpp"
#include "gcmap/mapping/mapper.hpp"
#include "gcmap/odometry/sweep_odometry.hpp"

namespace gcmap {

struct PipelineOptions {
  // The scans are KITTI's HDL-64 recordings: the 0.22 deg elevation correction applies (when
  // preprocess.kitti_vertical_correction is on).
  bool kitti_hdl64 = false;
  // Per-beam elevation offsets for the raw scans; when null, loaded from
  // preprocess.elevation_calibration (see with_elevation_calibration).
  std::shared_ptr<const ElevationCalibration> elevation_calibration;
};

// The options with the calibration file named by config.elevation_calibration loaded, unless they
// carry one. Throws Error naming the file.
PipelineOptions with_elevation_calibration(PipelineOptions options, const PreprocessConfig& config);

// One scan's outcome.
struct Frame {
  int index = 0;
  double stamp = 0.0;
  FrameStatus status = FrameStatus::unusable;
  // Current estimate, frame 0 the identity; later insertions and the final optimization move it.
  Eigen::Isometry3d T_world_frame = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d T_odom = Eigen::Isometry3d::Identity();  // odometry, or the given guess
  size_t points = 0;                                         // after preprocessing
  bool deskewed = false;
  bool odometry_failed = false;      // registration rejected (see Odometry::estimate): placed by the prediction
  RegistrationQuality registration;  // the odometry's registration of it (mapping/quality.hpp)
  double deskew_shift = 0.0;         // m, mean over points
};

struct PipelineStats {
  size_t frames = 0, unusable = 0;
  size_t odometry_failures = 0;                         // frames with Frame::odometry_failed
  size_t imu_samples = 0;                               // IMU samples given (add_imu)
  size_t gyro_deskewed = 0;                             // sweeps deskewed with the gyro's rotation
  size_t inertial_predicted = 0;                        // sweeps started from the LiDAR-inertial state (imu.inertial_odometry)
  size_t inertial_deskewed = 0;                         // sweeps deskewed with that state's motion
  std::optional<ImuBias> inertial_bias;                 // that state's biases at the end (IMU frame)
  std::optional<double> inertial_gravity_turn_deg;      // how far its gravity turned from its start's
  Eigen::Vector3d gyro_bias = Eigen::Vector3d::Zero();  // rad/s, LiDAR frame, the last estimate
  std::optional<GyroTrack::ClockCheck> imu_clock;       // the gyro's rates against the registered ones
  std::optional<int> gyro_rejected_at;                  // see SweepOdometry::gyro_rejected_at
  double deskew_gyro_noise = 0.0;                       // rad/s/sqrt(Hz), at the end (SweepOdometry::deskew_gyro_noise)
  GravityStats gravity;                                 // the accelerometer in the global graph
  TimingStats preprocess, odometry;                     // preprocess overlaps the other stages in run()
  MapperStats mapper;
  double seconds = 0.0;  // from construction to finish()
};

// A raw scan turned into what odometry and mapping take; made by prepare() on any thread.
struct PreparedScan {
  std::shared_ptr<PointCloud> cloud;      // null: unusable (see error)
  std::optional<KeyframeShape> keyframe;  // MappingPipeline::prepare's, unless the odometry will deskew the cloud
  double stamp = 0.0;
  double preprocess_ms = 0.0;
  std::string error;
};

// Corrections, label-based removal, downsampling and covariances of one raw scan (thread-safe).
// Per-point times of a spinning sensor's sweep from each point's azimuth (preprocess.sweep_*), in
// [0, sweep_period); prepare_scan sets them when preprocess.deskew_from_azimuth is on and the scan has none.
void times_from_azimuth(PointCloud& cloud, const PreprocessConfig& config);

// backend (may be null: the CPU) estimates the covariances.
PreparedScan prepare_scan(PointCloud raw, double stamp, const PreprocessConfig& config, const PipelineOptions& options,
                          LinearizationBackend* backend = nullptr);

class MappingPipeline {
 public:
  // backend: where factors are linearized (default: the CPU). Throws Error naming a bad config key.
  explicit MappingPipeline(const MappingConfig& config, std::shared_ptr<LinearizationBackend> backend = nullptr,
                           PipelineOptions options = {});

  // One scan in the sensor frame, stamps non-decreasing. scan.times, when present, are per-point
  // times in seconds relative to `stamp` and drive motion compensation (preprocess.deskew).
  // T_odom: an external odometry pose (e.g. from a prior trajectory) used instead of scan matching.
  // An empty, NaN-only or too small scan is no error: its frame is unusable and placed by the
  // motion model. Throws Error for a stamp going backwards or a scan after finish().
  Frame add_scan(PointCloud scan, double stamp, std::optional<Eigen::Isometry3d> T_odom = std::nullopt);
  // The two halves of add_scan: prepare() is const and thread-safe, add_prepared() takes frames in order.
  PreparedScan prepare(PointCloud scan, double stamp) const;
  Frame add_prepared(PreparedScan scan, std::optional<Eigen::Isometry3d> T_odom = std::nullopt);
  // Closes the open submap and runs the final optimization (at most max_final_iterations when
  // given, 0 skips it: for an interrupted run); add_scan is refused afterwards. on_iteration is
  // called after each iteration of the final optimization.
  void finish(std::optional<int> max_final_iterations = std::nullopt, const IterationCallback& on_iteration = {});
  bool finished() const { return finished_; }
  // An IMU sample (SweepOdometry::add_imu, Mapper::add_imu), before the scans it spans; ignored
  // unless imu.use.
  void add_imu(const ImuSample& sample);
  // GNSS fixes for the global graph (Mapper::set_gnss), before the first scan.
  void set_gnss(std::vector<GnssPosition> fixes) { mapper_.set_gnss(std::move(fixes)); }

  struct RunOptions {
    std::function<std::optional<Eigen::Isometry3d>(int frame)> initial_pose;  // external odometry
    // After each frame, from the mapping stage: the mapper's accessors (submaps(), factors(),
    // mapper()) may be read there; stamps(), odometry() and stats() change meanwhile.
    std::function<void(const Frame&)> on_frame;
    // When *stop turns true, no further scan is read and the insertion under way ends its global
    // optimization early, as does the closing one of finish(): *stop must outlive it.
    const std::atomic<bool>* stop = nullptr;
  };
  // Feeds every scan of the source through add_prepared, loading and preparing scans ahead in
  // parallel with the odometry and mapping of earlier frames, and the odometry of a frame in
  // parallel with the mapping of the one before. Does not finish(). Returns the frames added.
  size_t run(ScanSource& source, const RunOptions& options);

  const MappingConfig& config() const { return config_; }
  // The per-beam elevation offsets applied to every raw scan; null: none.
  const ElevationCalibration* elevation_calibration() const { return options_.elevation_calibration.get(); }
  const LinearizationBackend& backend() const { return *backend_; }
  size_t num_frames() const { return stamps_.size(); }
  const std::vector<double>& stamps() const { return stamps_; }
  const std::vector<FrameStatus>& statuses() const { return statuses_; }
  // Per frame: the odometry's registration figures and deskewing shift (Frame's), for quality.json.
  struct FrameFigures {
    RegistrationQuality registration;
    double deskew_shift = 0.0;
    bool usable = false;  // a scan the odometry could take
  };
  const std::vector<FrameFigures>& frame_figures() const { return frame_figures_; }
  std::vector<Eigen::Isometry3d> trajectory() const { return mapper_.trajectory(); }
  // The odometry's poses; a deskewed sweep's is revised once the next frame is registered (see
  // preprocess.redeskew), so it may differ from the T_odom its Frame returned.
  const std::vector<Eigen::Isometry3d>& odometry() const { return odometry_poses_; }
  const std::vector<Submap>& submaps() const { return mapper_.submaps(); }
  const Mapper& mapper() const { return mapper_; }
  const std::vector<GlobalFactor>& factors() const { return mapper_.factors(); }
  const std::vector<LoopRecord>& loops() const { return mapper_.loops(); }
  PipelineStats stats() const;
  // Every submap in the output frame (frame 0 the identity), voxel-downsampled.
  PointCloud map(double resolution) const { return mapper_.assemble_map(resolution); }

 private:
  MappingConfig config_;
  std::shared_ptr<LinearizationBackend> backend_;
  PipelineOptions options_;
  // add_prepared in two halves, which run() overlaps: the odometry of one frame while the mapper takes
  // the one before. Each half owns the members it writes.
  struct Tracked {
    Frame frame;
    std::shared_ptr<PointCloud> cloud;
    std::optional<KeyframeShape> keyframe;  // the prepared one, while the cloud was not deskewed
    std::optional<SweepRevision> revised;
    bool imu_rejected = false;         // the odometry dropped the IMU at this frame: so does the mapper
    std::optional<GyroRotation> gyro;  // since the previous frame
  };
  Tracked track_frame(PreparedScan scan, std::optional<Eigen::Isometry3d> T_odom);
  Frame map_frame(Tracked t);

  SweepOdometry odometry_;
  Mapper mapper_;
  std::vector<double> stamps_;
  std::vector<FrameStatus> statuses_;
  std::vector<FrameFigures> frame_figures_;  // track_frame's
  std::vector<Eigen::Isometry3d> odometry_poses_;
  size_t unusable_scans_ = 0, odometry_failures_ = 0, gyro_deskewed_ = 0, inertial_predicted_ = 0,
         inertial_deskewed_ = 0;  // track_frame's
  size_t imu_samples_ = 0;
  bool gyro_warned_ = false;
  size_t unusable_frames_ = 0;  // map_frame's
  TimingStats preprocess_ms_, odometry_ms_;
  Stopwatch clock_;
  double seconds_ = 0.0;
  bool finished_ = false;
};

}  // namespace gcmap
