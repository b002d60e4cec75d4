#pragma once
// The odometry front end the pipeline and the localizer share: scan-to-model registration
// (Odometry) with motion compensation of sweeps that carry per-point times (preprocess.deskew).
#include <deque>
#include <memory>
#include <optional>
#include <vector>

#include "gcmap/core/deskew.hpp"
#include "gcmap/graph/imu_preintegration.hpp"
#include "gcmap/odometry/gyro_track.hpp"
#include "gcmap/odometry/inertial_track.hpp"
#include "gcmap/odometry/odometry.hpp"
#include "gcmap/odometry/preprocess_scan.hpp"

namespace gcmap {

// An earlier frame's sweep deskewed again, now that more of the motion is known; the mapper should
// take its cloud and pose instead (Mapper::revise_frame).
struct SweepRevision {
  int frame = -1;  // its index among the frames tracked
  std::shared_ptr<const PointCloud> cloud;
  Eigen::Isometry3d T_world_frame = Eigen::Isometry3d::Identity();
};

struct SweepEstimate {
  Eigen::Isometry3d T_world_frame = Eigen::Isometry3d::Identity();  // at the scan stamp
  bool deskewed = false;
  bool gyro = false;             // deskewed with the IMU's rotation rates
  bool inertial = false;         // started from the LiDAR-inertial state's prediction
  bool inertial_motion = false;  // deskewed with that state's motion, not the registered one
  bool failed = false;           // registration rejected (see Odometry::estimate): placed by the prediction
  bool lost = false;             // the last of failed frames in a row: the next usable frame starts a new model
  RegistrationQuality quality;   // of the registration that placed the frame
  double deskew_shift = 0.0;     // m: how far deskewing moved the points, on average (0 when not deskewed)
  // At the second frame, the first sweep (it entered the odometry's model smeared); later, the
  // previous sweep, once this one is registered (see SweepOdometry::revise_previous).
  std::optional<SweepRevision> revised;
};

class SweepOdometry {
 public:
  // Reads preprocess.deskew and preprocess.redeskew of the preprocess section.
  SweepOdometry(const OdometryConfig& config, const PreprocessConfig& preprocess, const ImuConfig& imu,
                std::shared_ptr<LinearizationBackend> backend);

  // An IMU sample (its clock and frame, see ImuConfig), before the scans it spans; ignored unless
  // imu.use. Sweeps the samples span are deskewed with the gyro's rotation.
  void add_imu(const ImuSample& sample);
  const Eigen::Vector3d& gyro_bias() const { return gyro_.bias(); }  // rad/s, LiDAR frame
  // The gyro's rotation from t0 to t1, while the gyro is used and its samples span them.
  std::optional<GyroRotation> gyro_rotation(double t0, double t1) const;
  std::optional<GyroTrack::ClockCheck> imu_clock_check() const { return gyro_.clock_check(); }
  // The gyro noise density (rad/s/sqrt(Hz)) that weighs its deviation within a sweep: imu.gyro_noise,
  // or the one measured against the registered rotations where that is under 0.8 of it (a better
  // gyro than the config assumes: only the data tells how much of the deviation is signal).
  double deskew_gyro_noise() const;
  // The frame from which the gyro is no longer used, its rates not following the registered
  // rotation (GyroTrack::disagrees); empty while it is.
  std::optional<int> gyro_rejected_at() const { return gyro_rejected_at_; }
  // The LiDAR-inertial state's last biases (imu.inertial_odometry; IMU frame), once it was known.
  std::optional<ImuBias> inertial_bias() const { return inertial_enabled_ ? inertial_.last_bias() : std::nullopt; }
  std::optional<double> inertial_gravity_turn_deg() const {
    return inertial_enabled_ ? inertial_.last_gravity_turn_deg() : std::nullopt;
  }

  // The pose of a prepared scan (null: unusable, placed by the prediction) at `stamp`, stamps
  // non-decreasing. A scan with per-point times is deskewed in place into the sensor frame at the
  // stamp, unless no motion is known (the first frame, after a gap of odometry.max_gap). T_odom: an
  // external pose taken instead of registration (it still drives deskewing).
  SweepEstimate track(const std::shared_ptr<PointCloud>& cloud, double stamp,
                      const std::optional<Eigen::Isometry3d>& T_odom = std::nullopt);

 private:
  SweepEstimate track_deskewed(const std::shared_ptr<PointCloud>& cloud, double stamp, double dt);
  // A scan without point times, where the LiDAR-inertial state predicts it: registered from the
  // prediction and placed at the state's pose, as a deskewed sweep is.
  SweepEstimate track_fused(const std::shared_ptr<PointCloud>& cloud, double stamp, const Eigen::Isometry3d& guess);
  // What every frame ends with: the motion's history kept or dropped, the frame counted.
  SweepEstimate finish(SweepEstimate e, double stamp);
  // The IMU-propagated pose at `stamp`, when the inertial state is known and trusted.
  std::optional<Eigen::Isometry3d> inertial_guess(double stamp) const;
  // The registered rotation rates scatter clearly more than the gyro's noise explains.
  bool registration_noisier() const;

  // A registered mean velocity [omega; rho] between two instants, and the middle of them.
  struct MeanVelocity {
    Vector6d velocity = Vector6d::Zero();
    double time = 0.0;
  };
  // The gyro's rotations R_stamp_t over a sweep, at t = t0 + k step (s after the stamp).
  struct GyroSweep {
    double t0 = 0.0, step = 1e-3;
    std::vector<Eigen::Matrix3d> R;
  };
  // The motion over a sweep: velocity at `anchor` (s after the stamp), changing by acceleration per
  // second, a quadratic in the tangent space there (see deskew). With a gyro, the rotation is the
  // gyro's, plus a constant rate that makes it agree with the registered rotation since the last
  // sweep, and the translation follows it with the body-frame linear velocity of that quadratic.
  // Where the gyro's deviation from the quadratic's rotation is hardly above its noise (a steady
  // drive), that deviation is shrunk towards zero by gyro_weight (see weigh_gyro).
  struct SweepMotion {
    Vector6d velocity = Vector6d::Zero(), acceleration = Vector6d::Zero();
    double anchor = 0.0;
    std::shared_ptr<const GyroSweep> gyro;
    Eigen::Vector3d gyro_correction = Eigen::Vector3d::Zero();  // rad/s
    double gyro_weight = 1.0;
    Eigen::Isometry3d T_anchor(double t) const {
      const double u = t - anchor;
      return se3_exp(u * velocity + 0.5 * u * u * acceleration);
    }
    Eigen::Isometry3d T_stamp_model(double t) const { return T_anchor(0.0).inverse() * T_anchor(t); }
    Eigen::Isometry3d T_stamp(double t) const { return gyro ? poses().at(t) : T_stamp_model(t); }
    SweepPoses poses() const;  // with a gyro only
    void deskew(PointCloud& cloud) const;
    // The gyro's rotation (corrected) against the quadratic's at each entry of the gyro's table.
    std::vector<Eigen::Vector3d> gyro_deviation() const;
    // gyro_weight = (S - N) / S, at least 0: S the mean squared deviation, N what the gyro's white
    // noise (density gyro_noise, rad/s/sqrt(Hz)) alone would give, a random walk from the stamp.
    void weigh_gyro(double gyro_noise);
  };
  // The gyro's rotations over the sweep of `cloud` at `stamp` and since the last frame, or null.
  std::shared_ptr<const GyroSweep> gyro_sweep(const PointCloud& cloud, double stamp) const;

  // `mean` with the previous sweep's mean velocity: linear in time (constant without one), at the
  // stamp (anchoring it at the mean point time instead made no difference).
  SweepMotion sweep_motion(const MeanVelocity& mean, double stamp, std::shared_ptr<const GyroSweep> gyro) const;
  // The mean velocity up to `time` (absolute), where the sweep's registration put T_world_mean:
  // since the last sweep's reference, for a degenerate registration blended with that since the
  // one before (none: too close).
  std::optional<MeanVelocity> registered_mean(const Eigen::Isometry3d& T_world_mean, double time, bool degenerate) const;

  // The first sweep entered the model as it came; with the first motion registered (smeared
  // against smeared, which cancels), it is deskewed and the model started again from it.
  std::shared_ptr<const PointCloud> restart_from_first(const Vector6d& velocity);

  // A frame's pose at the instant its registration fixes best (see track_deskewed): the mean point
  // time of a deskewed sweep, else the scan stamp.
  struct SweepReference {
    Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
    double stamp = 0.0;  // absolute
  };
  // The frame's registration (or none) at `reference` joins the inertial state; the state's pose
  // there afterwards, which the frame takes, when the state was known before.
  std::optional<Eigen::Isometry3d> observe_inertial(const SweepEstimate& e, const SweepReference& reference);
  // The rate that makes the gyro's rotation from the last sweep's reference to `time`, where the
  // registration put T_world_mean, agree with the registered one: the gyro's noise and bias
  // integrated over that window, spread evenly (zero when too close).
  Eigen::Vector3d gyro_correction(const Eigen::Isometry3d& T_world_mean, double time) const;
  // The registered rotations over the last second refine the gyro's bias.
  void observe_gyro(const SweepReference& reference);
  // With the sweeps before and after it registered, the previous sweep is deskewed again by the
  // quadratic through the three references (its motion interpolated, no longer extrapolated).
  std::optional<SweepRevision> revise_previous(const SweepReference& next);

  OdometryConfig config_;
  std::shared_ptr<LinearizationBackend> backend_;
  bool deskew_, redeskew_;
  Odometry odometry_;
  bool use_imu_;
  double gyro_noise_;
  GyroTrack gyro_;
  bool inertial_enabled_;
  InertialTrack inertial_;
  std::deque<SweepReference> gyro_references_;  // the registered sweeps of the last second, in a row
  std::optional<int> gyro_rejected_at_;
  int frames_ = 0;
  struct FirstSweep {
    PointCloud raw;
    double stamp = 0.0;
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    int frame = 0;
  };
  std::optional<FirstSweep> first_;  // until the second frame is registered
  // The previous frame's pose and stamp.
  std::optional<std::pair<Eigen::Isometry3d, double>> last_;
  SweepReference reference_;                   // the last frame's
  std::optional<MeanVelocity> previous_mean_;  // the last deskewed sweep's
  // The last two registered sweeps in a row, the later one still revisable (as it came, its
  // deskewed cloud, stamp and frame index); reset by a frame registered otherwise.
  std::optional<SweepReference> before_previous_;
  struct Revisable {
    SweepReference reference;
    PointCloud raw;
    std::shared_ptr<const PointCloud> cloud;
    double stamp = 0.0;
    int frame = 0;
    SweepMotion motion;  // what it was deskewed with, at this pose
    Eigen::Isometry3d T_world_frame = Eigen::Isometry3d::Identity();
  };
  std::optional<Revisable> previous_;
};

}  // namespace gcmap
