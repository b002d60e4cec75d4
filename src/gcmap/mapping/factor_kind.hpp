#pragma once

namespace gcmap {

// matching_cost: VGICP between two submaps (the paper); odometry: a relative pose where a submap
// would otherwise be disconnected; se3: the ablation's scan-matching relative pose; loop: explicit.
enum class FactorKind { matching_cost, odometry, se3, loop };
inline constexpr FactorKind kFactorKinds[] = {FactorKind::matching_cost, FactorKind::odometry, FactorKind::se3, FactorKind::loop};
// As graph.json and sessions spell it.
const char* to_string(FactorKind kind);

// A factor of a global graph as sessions record it: its submaps and their overlap at creation.
struct FactorRecord {
  FactorKind kind = FactorKind::matching_cost;
  int source = 0, target = 0;
  double overlap = 0.0;
};

}  // namespace gcmap
