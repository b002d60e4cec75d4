#pragma once
#include <deque>
#include <memory>
#include <optional>

#include "gcmap/core/gaussian_voxel_map.hpp"
#include "gcmap/graph/backend.hpp"

namespace gcmap {

// Each key's meaning, unit and valid range: the config table (mapping/config.cpp), docs/config.md.
struct OdometryConfig {
  double voxel_resolution = 0.7;   // scan-to-model VGICP
  int model_keyframes = 10;        // recent keyframes in the local model
  double keyframe_distance = 1.0;  // m
  double keyframe_angle_deg = 10.0;
  int max_iterations = 32;
  // Constant-velocity prediction on real stamps: the last motion scaled by (this interval / the
  // last), at most max_interval_ratio; after a gap over max_gap s no motion is predicted.
  double max_interval_ratio = 10.0;
  double max_gap = 2.0;  // s
  // A registration matching fewer than retry_inlier_fraction of the points is retried (zero
  // motion, coarser voxels); if it still does and lands over retry_distance m from the prediction,
  // or matches under half of what the recent registrations matched, the frame is placed by the
  // prediction.
  double retry_distance = 1.0;
  double retry_inlier_fraction = 0.7;
  // Before any motion is known (the second frame, or after a gap of max_gap) the guess is standing
  // still, which a scan-to-scan cost on fine voxels confirms even at speed: the ground rings of one
  // sensor pose fall on themselves, and road-parallel structure does not object. The search starts
  // on voxels this large (m), where the rings blur into a plane.
  double start_voxel_resolution = 8.0;
};

// Why a frame was placed by the prediction instead of its registration (see Odometry::estimate).
enum class OdometryFailure { none, no_matches, stops_short, far_with_low_overlap, overlap_collapsed };
const char* to_string(OdometryFailure f);

// A registration whose translation is this poorly conditioned (RegistrationQuality::conditioning;
// smallest over largest eigenvalue) sees mostly parallel structure (a straight road's rails, a tunnel):
// its sweep gets the two-sweep velocity, the LiDAR-inertial state drops that direction, and gravity
// windows leave the frame out.
constexpr double kDegenerateConditioning = 0.1;

// What a frame's accepted scan-to-model registration says about itself, from the Hessian the
// registration built anyway (quality.json). Translation information is the Hessian's translation
// block with the rotation marginalized (Schur complement), per inlier point.
struct RegistrationQuality {
  bool registered = false;  // false: no registration (first frame, unusable scan, external pose)
  Eigen::Vector3d translation_information = Eigen::Vector3d::Zero();  // eigenvalues, ascending (1/m^2)
  Eigen::Vector3d weak_direction = Eigen::Vector3d::UnitX();          // unit, in the frame: the least constrained translation
  double inlier_fraction = 0.0;                                       // of the frame's points
  Matrix6d hessian = Matrix6d::Zero();                                // the registration's, over [rotation, translation]
  OdometryFailure failure = OdometryFailure::none;
  // Smallest over largest translation eigenvalue: 1 constrained alike in every direction, near 0 degenerate.
  double conditioning() const {
    return translation_information[2] > 0.0 ? translation_information[0] / translation_information[2] : 0.0;
  }
};

// LiDAR-only front end: scan-to-model VGICP against a voxel map of recent keyframes, started from
// a constant-velocity prediction that follows the scan stamps (frames without stamps are taken
// as equally spaced).
class Odometry {
 public:
  // backend: where registrations run (graph/backend.hpp; default the CPU).
  explicit Odometry(const OdometryConfig& config, std::shared_ptr<LinearizationBackend> backend = nullptr);

  // T_world_frame of a preprocessed frame (with covariances) taken at `stamp` (s). A frame too
  // small to register (empty or dropped scan) gets the prediction and *ok = false; a frame whose
  // registration fails (see estimate) gets the prediction and last_failed(); after 3 such frames in
  // a row the model is dropped, and the next usable frame starts a new one at the prediction. The
  // model keeps the frame: it must not change afterwards (it is subtracted from the model as it
  // ages out). guess: a prediction from elsewhere (an IMU) taken instead of the constant-velocity one.
  Eigen::Isometry3d track(const std::shared_ptr<const PointCloud>& frame, std::optional<double> stamp = std::nullopt,
                          bool* ok = nullptr, const std::optional<Eigen::Isometry3d>& guess = std::nullopt);
  // What a prediction rests on: no motion known (the second frame, after a gap of
  // odometry.max_gap, or after 3 frames in a row placed by the prediction); the last motion over
  // an equal interval (within 1.5x: driver jitter); the last motion scaled to another interval.
  enum class Guess { rest, steady, scaled };
  Guess guess_kind(std::optional<double> stamp = std::nullopt) const;
  // The two halves of track() for a usable frame: scan-to-model registration from a guess (no
  // state change), then the accepted pose and possibly a new keyframe of the model (or no model).
  // From rest, the search starts on odometry.start_voxel_resolution and its result is taken.
  // Otherwise a registration matching fewer than odometry.retry_inlier_fraction of the points
  // (and, from a steady guess, landing over odometry.retry_distance from it or matching under half
  // of what the recent registrations matched) is retried from zero motion (the last pose) and on
  // coarser voxels, the result with most inliers kept; one that stops odometry.retry_distance
  // short of a steady guess is retried from the guess on coarser voxels. When the result still
  // stops that short, or still matches so few and lands that far or matches under that half, or
  // hardly any point matches, the guess is returned and *failed set.
  // quality, when given, receives the figures of the registration returned (or why it failed).
  Eigen::Isometry3d estimate(const PointCloud& frame, const Eigen::Isometry3d& guess, Guess kind, bool* failed = nullptr,
                             RegistrationQuality* quality = nullptr) const;
  // quality: of the registration that placed the frame (its inlier fraction joins the recent ones).
  // A frame becomes a keyframe past keyframe_distance or keyframe_angle_deg from the last one, and
  // every registered frame does while the model holds fewer than model_keyframes. A failed frame
  // never does, unless an IMU placed it (imu_placed: T is its state's pose, not a guess).
  void accept(const std::shared_ptr<const PointCloud>& frame, const Eigen::Isometry3d& T,
              std::optional<double> stamp = std::nullopt, bool failed = false, const RegistrationQuality& quality = {},
              bool imu_placed = false);
  bool has_model() const { return model_ != nullptr; }
  bool last_failed() const { return last_failed_; }
  const RegistrationQuality& last_quality() const { return last_quality_; }  // of track()'s last frame

  // The constant-velocity guess for a frame at `stamp` (also used for frames that fail to load):
  // the last motion scaled by the ratio of the intervals in the tangent space.
  Eigen::Isometry3d predict(std::optional<double> stamp = std::nullopt) const;
  // Accepts an externally given pose (e.g. --initial-trajectory) to keep the motion model going.
  void set_pose(const Eigen::Isometry3d& T, std::optional<double> stamp = std::nullopt);
  // A keyframe of the model (`old`, the cloud it was accepted with) replaced by another cloud at
  // pose T (the sweep deskewed again); false when `old` is no keyframe (any more).
  bool revise_keyframe(const PointCloud& old, const std::shared_ptr<const PointCloud>& frame, const Eigen::Isometry3d& T);

 private:
  void add_keyframe(const std::shared_ptr<const PointCloud>& frame, const Eigen::Isometry3d& T);
  std::shared_ptr<const GaussianVoxelMap> model_at(double resolution) const;  // the keyframes on other voxels
  // Inlier fraction of the recent accepted registrations against the current model (median), 0
  // while too few are known.
  double typical_inlier_fraction() const;

  OdometryConfig config_;
  std::shared_ptr<LinearizationBackend> backend_;
  int frames_ = 0;
  bool last_failed_ = false;
  RegistrationQuality last_quality_;
  int failed_streak_ = 0;                // frames placed by the prediction in a row
  std::deque<double> inlier_fractions_;  // of the last accepted registrations, oldest first
  Eigen::Isometry3d last_ = Eigen::Isometry3d::Identity(), previous_ = Eigen::Isometry3d::Identity();
  std::optional<double> last_stamp_, previous_stamp_;
  std::deque<std::pair<Eigen::Isometry3d, std::shared_ptr<const PointCloud>>> keyframes_;
  // Updated in place (newest keyframe in, oldest out) unless a registration backend still holds
  // it (a GPU caches its last target): then copied first, so what it holds never changes.
  std::shared_ptr<GaussianVoxelMap> model_;
};

}  // namespace gcmap
