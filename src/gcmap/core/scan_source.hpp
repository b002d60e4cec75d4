#pragma once
// A recording as a sequence of scans (a sequence folder, a bag), read by the mapping pipeline.
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "gcmap/core/point_cloud.hpp"

namespace gcmap {

struct ScanRecord {
  double stamp = 0.0;  // s; per-point times (PointCloud::times) are seconds relative to it
  // Loads the scan; may run on a worker thread, in parallel with other scans' loads. Throws Error
  // when the scan cannot be read (the frame is then unusable, not the run).
  std::function<PointCloud()> load;
};

class ScanSource {
 public:
  virtual ~ScanSource() = default;
  // The next scan in time order, nullopt at the end. Called from one thread at a time.
  virtual std::optional<ScanRecord> next() = 0;
  // The number of scans when known in advance (progress and ETA), else 0.
  virtual size_t size_hint() const { return 0; }
  // What the input lacked (a truncated file, undecodable messages), one line each, for the run's
  // report; complete once next() has returned nullopt.
  virtual std::vector<std::string> warnings() const { return {}; }
};

}  // namespace gcmap
