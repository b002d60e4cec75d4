// ScanContext cost per submap: descriptor extraction per keyframe, and the queries of one submap's
// 15 keyframes against a database of 1500 places (a 100-submap map). Not a test.
#include <cstdio>

#include "gcmap/core/timer.hpp"
#include "gcmap/loop/scan_context.hpp"
#include "gcmap/odometry/preprocess_scan.hpp"
#include "gcmap/sim/simulator.hpp"

using namespace gcmap;

int main() {
  sim::SimulationConfig config;
  config.scenario = "small";
  const sim::Simulator simulator(config);
  std::vector<PointCloud> scans;
  for (size_t f = 0; f < simulator.num_frames(); ++f) scans.push_back(preprocess_scan(simulator.scan(f), PreprocessConfig{}));
  Stopwatch w;
  std::vector<ScanContext> descriptors;
  for (const auto& s : scans) descriptors.push_back(make_scan_context(s));
  const double extract_ms = w.lap_ms() / scans.size();
  ScanContextDatabase db;
  while (db.size() < 1500) db.add(descriptors[db.size() % descriptors.size()]);
  const int rounds = 20;
  w.lap_ms();
  double checksum = 0.0;
  for (int r = 0; r < rounds; ++r) {
    std::vector<const ScanContext*> queries;
    for (int k = 0; k < 15; ++k) queries.push_back(&descriptors[(7 * r + k) % descriptors.size()]);
    for (const auto& result : db.query(queries, db.size() - 75, 10)) checksum += result.match.distance;
  }
  const double per_submap_ms = w.lap_ms() / rounds;
  std::printf("descriptor: %.3f ms per keyframe (%zu points avg)\n", extract_ms, scans[0].size());
  std::printf("retrieval + matching: %.2f ms per submap (15 queries, 1500 places, 10 candidates)  [checksum %.3f]\n",
              per_submap_ms, checksum);
  std::printf("per submap incl. 15 descriptors: %.2f ms\n", per_submap_ms + 15 * extract_ms);
  return 0;
}
