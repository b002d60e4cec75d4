#pragma once
#include <map>
#include <memory>
#include <vector>

#include "gcmap/graph/factors.hpp"

namespace gcmap {

// Pose variables keyed by integer id.
using Values = std::map<int, Eigen::Isometry3d>;

struct FactorGraph {
  std::vector<std::shared_ptr<Factor>> factors;
  void add(std::shared_ptr<Factor> factor);
};

}  // namespace gcmap
