#include "progress.hpp"

#include <spdlog/spdlog.h>
#include <unistd.h>

#include <cstdio>

namespace gcmap::cli {

namespace {
std::string eta_text(double seconds) {
  char buf[32];
  const int s = static_cast<int>(seconds + 0.5);
  if (s >= 3600) std::snprintf(buf, sizeof buf, "%dh%02dm", s / 3600, s / 60 % 60);
  else std::snprintf(buf, sizeof buf, "%dm%02ds", s / 60, s % 60);
  return buf;
}
}  // namespace

namespace {
// The logger main() installs, kept while QuietWarnings puts a quiet one in its place.
std::shared_ptr<spdlog::logger> g_shown;
}  // namespace

QuietWarnings::QuietWarnings() {
  g_shown = spdlog::default_logger();
  auto quiet = g_shown->clone("quiet");
  quiet->set_level(spdlog::level::err);
  spdlog::set_default_logger(quiet);
}

QuietWarnings::~QuietWarnings() {
  spdlog::set_default_logger(g_shown);
  spdlog::drop("quiet");
  g_shown.reset();
}

Progress::Progress(std::string what, size_t total, bool quiet)
    : what_(std::move(what)), total_(total), quiet_(quiet), tty_(isatty(2)) {}

void Progress::update(size_t done, const std::string& detail) {
  if (quiet_) return;
  const double t = seconds();
  const bool last = total_ && done == total_;
  if (!last && t - last_log_s_ < (tty_ ? 0.2 : 5.0)) return;
  draw(done, detail);
}

void Progress::draw(size_t done, const std::string& detail) {
  const double t = seconds();
  last_log_s_ = t;
  const double rate = t > 0 ? done / t : 0.0;
  std::string line = what_ + " " + std::to_string(done);
  if (total_) line.append("/").append(std::to_string(total_));
  char buf[64];
  std::snprintf(buf, sizeof buf, "  %.1f/s", rate);
  if (rate_) line += buf;
  if (rate_ && total_ && rate > 0 && done < total_) line += "  ETA " + eta_text((total_ - done) / rate);
  if (!detail.empty()) line += "  " + detail;
  if (tty_) {
    std::fprintf(stderr, "\r%s\033[K", line.c_str());
    drawn_ = true;
  } else {
    (g_shown ? g_shown : spdlog::default_logger())->info("{}", line);
  }
}

void Progress::step(size_t done, const std::string& detail) {
  if (!quiet_) draw(done, detail);
}

void Progress::finish(size_t done, const std::string& detail) {
  if (!quiet_) draw(done, detail);
  finish();
}

void Progress::finish() {
  if (drawn_) std::fprintf(stderr, "\n");
  drawn_ = false;
}

}  // namespace gcmap::cli
