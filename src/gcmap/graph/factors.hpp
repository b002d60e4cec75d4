#pragma once
// Factors over SE(3) poses (right perturbations, shared/docs/vgicp-factor-math.md). Each gives its
// error and its Gauss-Newton linearization over the poses it touches:
// error(d) ~ error + 2 b^T d + d^T H d.
#include <array>
#include <memory>
#include <optional>

#include "gcmap/core/gaussian_voxel_map.hpp"
#include "gcmap/core/imu_sample.hpp"
#include "gcmap/core/point_cloud.hpp"
#include "gcmap/core/se3.hpp"
#include "gcmap/graph/robust_kernel.hpp"

namespace gcmap {

using Matrix12d = Eigen::Matrix<double, 12, 12>;
using Vector12d = Eigen::Matrix<double, 12, 1>;

// For a unary factor only the top-left 6x6 / head 6 are used.
struct FactorLinearization {
  Matrix12d H = Matrix12d::Zero();
  Vector12d b = Vector12d::Zero();
  double error = 0.0;
};

class Factor {
 public:
  virtual ~Factor() = default;
  virtual int num_keys() const = 0;
  const std::array<int, 2>& keys() const { return keys_; }

  // poses[k] is the pose of keys()[k].
  virtual void linearize(const Eigen::Isometry3d* const* poses, FactorLinearization& out) = 0;
  // Error at trial poses, judged with what was frozen at the last linearization (voxel association,
  // robust weight), so LM's gain ratio compares like with like.
  virtual double trial_error(const Eigen::Isometry3d* const* poses) const = 0;
  // Worth keeping its last linearization for reuse while its poses barely move (graph/lazy_backend.hpp);
  // such a factor's cost must depend on the relative pose T_1^-1 T_0 of its keys only.
  virtual bool reusable() const { return false; }
  // Frees what linearize() kept for the trials that follow it; LevenbergMarquardt calls it when an
  // optimize() call ends.
  virtual void release_trial_state() {}

  // The linearization a lazy backend keeps, with the poses it was taken at.
  struct Kept {
    std::array<Eigen::Isometry3d, 2> poses;
    FactorLinearization lin;
  };
  std::optional<Kept> kept;

 protected:
  std::array<int, 2> keys_{-1, -1};
};

struct VgicpLinearization;
// The two-pose blocks of a VGICP linearization in factor layout (source pose first).
void to_factor_linearization(const VgicpLinearization& lin, FactorLinearization& out);

// How a MatchingCostFactor's trial errors find the voxels of its last linearization: looked up
// again, or kept from it, 4 bytes per source point: for the factor's life (kept: graphs that live
// only through one optimization), or until its optimize() call ends (kept_per_optimization: the
// global graph). The latter share a process-wide cap of kMaxKeptAssociations points (256 MB), which
// bounds a final optimization that re-linearizes every factor of a long drive; beyond it, factors
// look up. The lookups are most of a trial's cost (docs/benchmarks.md); trial errors are the same
// either way.
enum class TrialVoxels { look_up, kept, kept_per_optimization };
constexpr long kMaxKeptAssociations = 1L << 26;
// Points whose voxels kept_per_optimization factors hold now.
long kept_associations();

// VGICP matching cost between a source cloud (key i) and a target voxel map (key j), paper Eq. 1-6.
// Association and fused covariances are recomputed at every linearization; trial errors keep that
// association (see TrialVoxels).
class MatchingCostFactor : public Factor {
 public:
  MatchingCostFactor(int source_key, int target_key, std::shared_ptr<const PointCloud> source,
                     std::shared_ptr<const GaussianVoxelMap> target, TrialVoxels trial_voxels = TrialVoxels::look_up);
  ~MatchingCostFactor() override;
  MatchingCostFactor(const MatchingCostFactor&) = delete;
  MatchingCostFactor& operator=(const MatchingCostFactor&) = delete;
  int num_keys() const override { return 2; }
  void linearize(const Eigen::Isometry3d* const* poses, FactorLinearization& out) override;
  double trial_error(const Eigen::Isometry3d* const* poses) const override;
  bool reusable() const override { return true; }
  void release_trial_state() override;

  // Linearizations drop a translation held by less than this (drop_weak_translation,
  // registration/vgicp.hpp); 0: never. The global graph's factors do (global.min_conditioning).
  void set_min_conditioning(double min_conditioning) { min_conditioning_ = min_conditioning; }
  // lin (at T_target_source) after that; for backends that linearize on their own.
  VgicpLinearization conditioned(const VgicpLinearization& lin, const Eigen::Isometry3d& T_target_source) const;
  // Each point's information weighted by c^2 / (c^2 + m2) (linearize_vgicp, registration/vgicp.hpp);
  // 0: not weighted. The keyframe graph's and the global graph's factors are (local.robust_width,
  // global.robust_width).
  void set_robust_width(float robust_width) { robust_width_ = robust_width; }
  float robust_width() const { return robust_width_; }

  const PointCloud& source() const { return *source_; }
  const GaussianVoxelMap& target() const { return *target_; }
  const std::shared_ptr<const PointCloud>& source_ptr() const { return source_; }
  const std::shared_ptr<const GaussianVoxelMap>& target_ptr() const { return target_; }

 private:
  std::shared_ptr<const PointCloud> source_;
  std::shared_ptr<const GaussianVoxelMap> target_;
  Eigen::Isometry3d T_lin_ = Eigen::Isometry3d::Identity();  // T_target_source at the last linearization
  TrialVoxels trial_voxels_;
  std::vector<int> associations_;  // kept: each source point's voxel at T_lin_
  long counted_ = 0;               // kept_per_optimization: points of associations_ under the cap
  double min_conditioning_ = 0.0;
  float robust_width_ = 0.f;
};

// SE(3) constraint T_i^-1 T_j ~ measured, error = log(measured^-1 T_i^-1 T_j) whitened by a 6x6
// information matrix (paper Eq. 10), with an IRLS robust kernel whose weight is refreshed at each
// linearization.
class RelativePoseFactor : public Factor {
 public:
  RelativePoseFactor(int key_i, int key_j, const Eigen::Isometry3d& measured_T_i_j, const Matrix6d& information,
                     RobustKernel kernel = {});
  int num_keys() const override { return 2; }
  void linearize(const Eigen::Isometry3d* const* poses, FactorLinearization& out) override;
  double trial_error(const Eigen::Isometry3d* const* poses) const override;

  Vector6d residual(const Eigen::Isometry3d& T_i, const Eigen::Isometry3d& T_j) const;
  double weight() const { return weight_; }
  const RobustKernel& kernel() const { return kernel_; }

 private:
  Eigen::Isometry3d measured_;
  Matrix6d information_;
  RobustKernel kernel_;
  double weight_ = 1.0;
};

// The gyro's rotation from pose i to pose j (in pose i's frame) as their relative rotation, over
// its variance; their relative translation is left free.
std::shared_ptr<RelativePoseFactor> gyro_rotation_factor(int key_i, int key_j, const GyroRotation& gyro);
// The same with the relative translation t_i_j (in pose i's frame) measured too, at translation_sigma
// (m) per axis.
std::shared_ptr<RelativePoseFactor> gyro_motion_factor(int key_i, int key_j, const GyroRotation& gyro,
                                                       const Eigen::Vector3d& t_i_j, double translation_sigma);

}  // namespace gcmap
