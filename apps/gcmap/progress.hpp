#pragma once
// Progress of long work for a person: a live line on a terminal, or a log line every few seconds
// when stderr is not a terminal (a job scheduler's log).
#include <cstddef>
#include <string>

#include "gcmap/core/timer.hpp"

namespace gcmap::cli {

class Progress {
 public:
  // total 0: unknown (no ETA). quiet: nothing at all.
  Progress(std::string what, size_t total, bool quiet);
  // done items so far; detail is appended to the line.
  void update(size_t done, const std::string& detail = {});
  // Ends the terminal line.
  void finish();
  double seconds() const { return clock_.ms() / 1000.0; }

 private:
  std::string what_;
  size_t total_;
  bool quiet_, tty_;
  Stopwatch clock_;
  double last_log_s_ = 0.0;
  bool drawn_ = false;
};

}  // namespace gcmap::cli
