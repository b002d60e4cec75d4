#pragma once
// Scene builders that fill a World. The city's street blocks keep the historical random sequence
// (same seed, same world); the realism additions draw from their own streams.
#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "gcmap/sim/world.hpp"

namespace gcmap::sim {

// Buildings, street furniture, parked cars and garden walls in every block between the streets on
// the grid lines of [lo, hi] (in blocks); flat facades only when feature_poor; blocks x in
// [tunnel.x(), tunnel.y()) one flat wall joined across the cross streets.
void build_city_blocks(World& world, uint64_t seed, float block, Eigen::Vector2i lo, Eigen::Vector2i hi, bool feature_poor,
                       Eigen::Vector2i tunnel = Eigen::Vector2i::Zero());

// Raised sidewalks (15 cm kerbs) around every block of the grid.
void add_sidewalks(World& world, float block, Eigen::Vector2i lo, Eigen::Vector2i hi);

// The map changes over a drive of `duration` seconds: some parked cars leave, some arrive; some
// cars are dark (weak returns).
void add_parked_car_dynamics(World& world, uint64_t seed, float duration);
// Canopies and bushes let rays through (partial returns) or, when `on` is false, are solid.
void set_porous_vegetation(World& world, uint64_t seed, bool on);

// A divided highway along `center` (dense polyline): guardrails, a median barrier, sparse poles,
// trees and buildings away from the road.
void build_highway(World& world, uint64_t seed, const std::vector<Eigen::Vector2f>& center);

// Woodland around a trail along `trail`: trees with porous canopies, bushes, rocks, a few logs.
void build_forest(World& world, uint64_t seed, const std::vector<Eigen::Vector2f>& trail);

}  // namespace gcmap::sim
