#include <gtest/gtest.h>
#include <unistd.h>

#include <fstream>
#include <vector>

#include "gcmap/core/memory.hpp"

namespace gcmap {
namespace {

// Resident set size now, from /proc/self/statm (pages).
size_t current_rss_bytes() {
  std::ifstream statm("/proc/self/statm");
  size_t total = 0, resident = 0;
  statm >> total >> resident;
  return resident * static_cast<size_t>(sysconf(_SC_PAGESIZE));
}

TEST(Memory, PeakRssCoversATouchedBuffer) {
  if (!std::ifstream("/proc/self/statm")) GTEST_SKIP() << "no /proc/self/statm";
  std::vector<char> buffer(64 << 20);
  for (size_t i = 0; i < buffer.size(); i += 4096) buffer[i] = static_cast<char>(i);
  // The kernel counts resident pages lazily (per-thread batches), so compare with the buffer.
  EXPECT_GE(current_rss_bytes(), buffer.size());
  const size_t peak = peak_rss_bytes();
  EXPECT_GE(peak, buffer.size());
  buffer = std::vector<char>();
  EXPECT_GE(peak_rss_bytes(), peak);  // a peak, not the current size
}

}  // namespace
}  // namespace gcmap
