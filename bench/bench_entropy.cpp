// Mean map entropy on a ~10 M-point map: raw scans of the simulated `small` scenario stacked at their
// ground-truth poses. Prints points/s for 1 and 2 threads. Not a test.
#include <tbb/global_control.h>

#include <cstdio>

#include "gcmap/core/timer.hpp"
#include "gcmap/eval/map_entropy.hpp"
#include "gcmap/sim/simulator.hpp"

using namespace gcmap;

int main(int argc, char** argv) {
  const size_t target = argc > 1 ? std::stoul(argv[1]) : 10'000'000;
  sim::SimulationConfig config;
  config.scenario = "small";
  const sim::Simulator simulator(config);
  PointCloud map;
  for (size_t f = 0; f < simulator.num_frames() && map.size() < target; ++f) {
    const PointCloud scan = simulator.scan(f);
    const PointCloud world = transformed(scan, simulator.poses()[f]);
    map.points.insert(map.points.end(), world.points.begin(), world.points.end());
  }
  std::printf("map: %zu points\n", map.size());
  for (int threads : {2, 1}) {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
    Stopwatch sw;
    const MapEntropy e = mean_map_entropy(map);
    const double s = sw.ms() / 1000.0;
    std::printf("threads=%d  %.2f s  %.2f M points/s  mme=%.4f std=%.4f used=%zu skipped=%zu\n", threads, s, map.size() / s / 1e6,
                e.mean, e.stddev, e.num_points, e.num_skipped);
    if (map.size() > 3'000'000) break;  // one thread on the full map takes too long to be worth it
  }
  return 0;
}
