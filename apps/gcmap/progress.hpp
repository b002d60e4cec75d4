#pragma once
// Progress of long work for a person: a live line on a terminal, or a log line every few seconds
// when stderr is not a terminal (a job scheduler's log).
#include <cstddef>
#include <functional>
#include <string>

#include "gcmap/core/timer.hpp"

namespace gcmap::cli {

// While alive, warnings of the library (the default logger's) are not shown; Progress lines still
// are. For work that reads the input ahead of the run, which reports the same problems itself.
class QuietWarnings {
 public:
  QuietWarnings();
  ~QuietWarnings();
  QuietWarnings(const QuietWarnings&) = delete;
  QuietWarnings& operator=(const QuietWarnings&) = delete;
};

class Progress {
 public:
  // total 0: unknown (no ETA). quiet: nothing at all.
  Progress(std::string what, size_t total, bool quiet);
  // Leaves out the rate and ETA: for items of unequal length (steps; iterations up to a maximum
  // that is seldom reached).
  void without_rate() { rate_ = false; }
  // update() as a callback of (done, total). The total goes in the detail, not in the count: the
  // last item then forces no line, so a quick load stays silent in a log (where a failure after it
  // must remain the only line).
  std::function<void(size_t, size_t)> callback() {
    return [this](size_t done, size_t total) { update(done, "(of " + std::to_string(total) + ")"); };
  }
  // done items so far; detail is appended to the line.
  void update(size_t done, const std::string& detail = {});
  // Draws the line now, however soon after the one before: steps of a few long items.
  void step(size_t done, const std::string& detail);
  // Ends the terminal line.
  void finish();
  // Draws a last line, however soon after the one before (its counts are the final ones), and ends it.
  void finish(size_t done, const std::string& detail);
  double seconds() const { return clock_.ms() / 1000.0; }

 private:
  std::string what_;
  size_t total_;
  bool quiet_, tty_;
  Stopwatch clock_;
  double last_log_s_ = 0.0;
  bool drawn_ = false, rate_ = true;

  void draw(size_t done, const std::string& detail);
};

}  // namespace gcmap::cli
