#include "gcmap/graph/matching_graph.hpp"

#include <tbb/parallel_for.h>

namespace gcmap {

std::vector<PairOverlap> add_overlapping_pairs(FactorGraph& graph, const std::vector<ScanNode>& nodes,
                                               const Values& values, double min_overlap) {
  std::vector<PairOverlap> pairs;
  for (int j = 0; j < static_cast<int>(nodes.size()); ++j)
    for (int i = 0; i < j; ++i) pairs.push_back({j, i, 0.0});
  tbb::parallel_for(size_t{0}, pairs.size(), [&](size_t k) {
    PairOverlap& p = pairs[k];
    p.overlap = overlap(*nodes[p.source].cloud, *nodes[p.target].voxels,
                        values.at(p.target).inverse() * values.at(p.source));
  });
  std::vector<PairOverlap> kept;
  for (const PairOverlap& p : pairs) {
    if (p.overlap < min_overlap) continue;
    graph.add(std::make_shared<MatchingCostFactor>(p.source, p.target, nodes[p.source].cloud, nodes[p.target].voxels));
    kept.push_back(p);
  }
  return kept;
}

}  // namespace gcmap
