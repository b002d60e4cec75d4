#include "gcmap/graph/factor_graph.hpp"

#include "gcmap/core/error.hpp"

namespace gcmap {

void FactorGraph::add(std::shared_ptr<Factor> factor) {
  if (factor->num_keys() == 2 && factor->keys()[0] == factor->keys()[1])
    throw Error("a factor cannot connect pose " + std::to_string(factor->keys()[0]) + " to itself");
  factors.push_back(std::move(factor));
}

}  // namespace gcmap
