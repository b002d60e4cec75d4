#include "gcmap/core/timer.hpp"

#include <algorithm>
#include <cmath>

namespace gcmap {

double TimingStats::mean() const {
  if (samples_ms.empty()) return 0.0;
  double s = 0;
  for (double v : samples_ms) s += v;
  return s / samples_ms.size();
}

double TimingStats::stddev() const {
  if (samples_ms.size() < 2) return 0.0;
  const double m = mean();
  double s = 0;
  for (double v : samples_ms) s += (v - m) * (v - m);
  return std::sqrt(s / samples_ms.size());
}

double TimingStats::max() const { return samples_ms.empty() ? 0.0 : *std::max_element(samples_ms.begin(), samples_ms.end()); }

}  // namespace gcmap
