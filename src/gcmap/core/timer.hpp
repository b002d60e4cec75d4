#pragma once
#include <chrono>

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

}  // namespace gcmap
