#pragma once
// Classic GICP (Segal et al. 2009): each source point is matched to its nearest target point
// within a distance, with the same per-point cost as VGICP but the target point's own Gaussian.
// Used where voxel matching is the thing being checked: loop verification and the SE(3) ablation.
#include <memory>
#include <vector>

#include "gcmap/core/kdtree.hpp"
#include "gcmap/registration/vgicp.hpp"

namespace gcmap {

// A cloud with covariances and a kd-tree over its points.
class GicpTarget {
 public:
  explicit GicpTarget(std::shared_ptr<const PointCloud> cloud);
  const PointCloud& cloud() const { return *cloud_; }
  const KdTree& tree() const { return tree_; }

 private:
  std::shared_ptr<const PointCloud> cloud_;
  KdTree tree_;
};

// Nearest target point of every source point under T_target_source; -1 beyond max_distance.
std::vector<int> find_correspondences(const PointCloud& source, const GicpTarget& target,
                                      const Eigen::Isometry3d& T_target_source, double max_distance);

// Blocks as for VGICP (source i, target j), for the given correspondences.
VgicpLinearization linearize_gicp(const PointCloud& source, const GicpTarget& target, const Eigen::Isometry3d& T_target_source,
                                  const std::vector<int>& correspondences);
VgicpError evaluate_gicp(const PointCloud& source, const GicpTarget& target, const Eigen::Isometry3d& T_target_source,
                         const std::vector<int>& correspondences);

}  // namespace gcmap
