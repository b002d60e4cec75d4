#pragma once
#include <chrono>
#include <vector>

namespace gcmap {

class Stopwatch {
 public:
  Stopwatch() : start_(std::chrono::steady_clock::now()) {}
  void restart() { start_ = std::chrono::steady_clock::now(); }
  double ms() const { return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start_).count(); }
  // Milliseconds since the last lap (or construction), then restarts.
  double lap_ms() {
    const double t = ms();
    restart();
    return t;
  }

 private:
  std::chrono::steady_clock::time_point start_;
};

// Every sample of one timed stage, for means, spreads and per-event curves.
struct TimingStats {
  std::vector<double> samples_ms;
  void add(double ms) { samples_ms.push_back(ms); }
  double mean() const;
  double stddev() const;
  double max() const;
};

}  // namespace gcmap
