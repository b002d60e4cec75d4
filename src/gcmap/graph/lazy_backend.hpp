#pragma once
// Re-linearize only what moved (issue: a global optimization per insertion that does not grow with
// the whole map). Each reusable factor keeps its last linearization and is linearized again only
// when its relative pose moved more than `threshold` since (the norm of the change's log over
// [rotation rad, translation m], as iSAM2's relinearizeThreshold); until then its blocks are that
// quadratic model of the relative pose carried to the current poses (through the relative pose's
// Jacobian there, so that a motion both poses share stays free), and its trial errors are the
// model's. Threshold 0 re-linearizes every factor whose poses moved at all: the same result as
// always re-linearizing.
// A budget bounds the work of one call: at most that many moved factors are linearized anew, those
// that moved most first, and the others stay models until a later call.
#include <memory>
#include <vector>

#include "gcmap/graph/backend.hpp"

namespace gcmap {

class LazyBackend : public LinearizationBackend {
 public:
  LazyBackend(std::shared_ptr<LinearizationBackend> inner, double threshold);
  void linearize(std::span<Factor* const> factors, std::span<const FactorPoses> poses,
                 std::span<FactorLinearization> out) override;
  void trial_errors(std::span<Factor* const> factors, std::span<const FactorPoses> poses, std::span<double> out) override;
  void overlaps(const std::shared_ptr<const PointCloud>& source, std::span<const std::shared_ptr<const GaussianVoxelMap>> targets,
                std::span<const Eigen::Isometry3d> T_target_source, std::span<double> out) override {
    inner_->overlaps(source, targets, T_target_source, out);
  }
  Device device() const override { return inner_->device(); }
  std::string name() const override { return inner_->name(); }

  // At most `max` moved factors linearized anew per call (0: no limit). Factors without a model
  // (new ones) are always linearized.
  void set_max_relinearizations(size_t max) { max_relinearizations_ = max; }

  // Factor linearizations run, reused, and deferred by the budget since construction.
  size_t linearized() const { return linearized_; }
  size_t reused() const { return reused_; }
  size_t deferred() const { return deferred_; }

 private:
  std::shared_ptr<LinearizationBackend> inner_;
  double threshold_;
  size_t max_relinearizations_ = 0;
  std::vector<char> modelled_;     // per factor of the last linearize(): its kept model stands in
  std::vector<Vector12d> motion_;  // per factor: its relative-pose change since it was kept
  // Buffers for the subset handed to the inner backend.
  std::vector<size_t> subset_, moved_;
  std::vector<Factor*> sub_factors_;
  std::vector<FactorPoses> sub_poses_;
  std::vector<FactorLinearization> sub_lin_;
  std::vector<double> sub_errors_;
  size_t linearized_ = 0, reused_ = 0, deferred_ = 0;
};

}  // namespace gcmap
