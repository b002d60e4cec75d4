#pragma once
// The seam where every factor of one LM iteration is linearized (or evaluated) in one call. The
// CPU backend runs factors in parallel (and each factor's points in parallel); a GPU backend can
// take the matching-cost factors as one device batch without the optimizer changing.
// Threads: linearize, trial_errors and overlaps come from one thread at a time (the mapper's);
// align and estimate_covariances may run beside them (the pipeline's odometry and scan preparation).
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "gcmap/core/preprocess.hpp"
#include "gcmap/graph/factor_graph.hpp"
#include "gcmap/registration/registration.hpp"

namespace gcmap {

// Where factors are linearized. auto: a GPU when one answers, else the CPU.
enum class Device { cpu, cuda, automatic };
// "cpu", "cuda" or "auto"; throws Error naming `key` (a config key or CLI flag) otherwise.
Device parse_device(const std::string& text, const std::string& key);
const char* device_name(Device device);

using FactorPoses = std::array<const Eigen::Isometry3d*, 2>;

class LinearizationBackend {
 public:
  virtual ~LinearizationBackend() = default;
  virtual void linearize(std::span<Factor* const> factors, std::span<const FactorPoses> poses,
                         std::span<FactorLinearization> out) = 0;
  virtual void trial_errors(std::span<Factor* const> factors, std::span<const FactorPoses> poses, std::span<double> out) = 0;
  // Paper Eq. 8 for one source against many targets: out[k] = overlap(source -> targets[k]) under
  // T_target_source[k]. The default runs on the CPU.
  virtual void overlaps(const std::shared_ptr<const PointCloud>& source,
                        std::span<const std::shared_ptr<const GaussianVoxelMap>> targets,
                        std::span<const Eigen::Isometry3d> T_target_source, std::span<double> out);
  // align_vgicp (registration/registration.hpp) of the odometry and the localizer. The default runs
  // on the CPU; a GPU backend evaluates the points on the device. Thread-safe.
  virtual RegistrationResult align(const PointCloud& source, const std::shared_ptr<const GaussianVoxelMap>& target,
                                   const Eigen::Isometry3d& init_T_target_source, const RegistrationConfig& config);
  // estimate_covariances (core/preprocess.hpp) of a scan being prepared. The default runs on the
  // CPU; a GPU backend runs it on the device. Thread-safe: scans are prepared on several threads.
  virtual void estimate_covariances(PointCloud& cloud, const CovarianceConfig& config);
  virtual Device device() const = 0;
  // For reports: "cpu" or "cuda: <device name>".
  virtual std::string name() const = 0;
};

class CpuBackend : public LinearizationBackend {
 public:
  void linearize(std::span<Factor* const> factors, std::span<const FactorPoses> poses,
                 std::span<FactorLinearization> out) override;
  void trial_errors(std::span<Factor* const> factors, std::span<const FactorPoses> poses, std::span<double> out) override;
  Device device() const override { return Device::cpu; }
  std::string name() const override { return "cpu"; }
};

struct TargetOverlap {
  int index;       // into the targets passed
  double overlap;  // overlap(source -> target)
};

// The targets whose overlap with the source reaches min_overlap, in target order (one backend call).
std::vector<TargetOverlap> overlapping_targets(LinearizationBackend& backend, const std::shared_ptr<const PointCloud>& source,
                                               std::span<const std::shared_ptr<const GaussianVoxelMap>> targets,
                                               std::span<const Eigen::Isometry3d> T_target_source, double min_overlap);

}  // namespace gcmap
