#pragma once
#include <map>
#include <memory>
#include <span>
#include <vector>

#include "gcmap/graph/factors.hpp"

namespace gcmap {

// Pose variables keyed by integer id.
using Values = std::map<int, Eigen::Isometry3d>;

struct FactorGraph {
  std::vector<std::shared_ptr<Factor>> factors;
  void add(std::shared_ptr<Factor> factor);
};

using FactorPoses = std::array<const Eigen::Isometry3d*, 2>;

// The seam where every factor of one LM iteration is linearized (or evaluated) in one call. The
// CPU backend runs factors in parallel (and each factor's points in parallel); a GPU backend can
// take the matching-cost factors as one device batch without the optimizer changing.
class LinearizationBackend {
 public:
  virtual ~LinearizationBackend() = default;
  virtual void linearize(std::span<Factor* const> factors, std::span<const FactorPoses> poses,
                         std::span<FactorLinearization> out) = 0;
  virtual void trial_errors(std::span<Factor* const> factors, std::span<const FactorPoses> poses,
                            std::span<double> out) = 0;
  // Paper Eq. 8 for one source against many targets: out[k] = overlap(source -> targets[k]) under
  // T_target_source[k]. The default runs on the CPU.
  virtual void overlaps(const std::shared_ptr<const PointCloud>& source,
                        std::span<const std::shared_ptr<const GaussianVoxelMap>> targets,
                        std::span<const Eigen::Isometry3d> T_target_source, std::span<double> out);
};

class CpuBackend : public LinearizationBackend {
 public:
  void linearize(std::span<Factor* const> factors, std::span<const FactorPoses> poses,
                 std::span<FactorLinearization> out) override;
  void trial_errors(std::span<Factor* const> factors, std::span<const FactorPoses> poses,
                    std::span<double> out) override;
};

}  // namespace gcmap
