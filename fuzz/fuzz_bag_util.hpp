#pragma once
// Shared by the bag fuzz targets: open the bytes as a bag, read every topic and decode every point
// cloud. Only gcmap::Error may come out; anything else escapes and libFuzzer reports it.
#include <cstdint>
#include <cstdlib>
#include <string>

#include <spdlog/spdlog.h>

#include "gcmap/core/error.hpp"
#include "gcmap/io/bag_scans.hpp"

namespace gcmap::fuzz {

// Decoded scans must be self-consistent: channels absent or one entry per point, times >= 0.
inline void check_scan(const BagScan& s) {
  const size_t n = s.cloud.size();
  if (!s.cloud.intensities.empty() && s.cloud.intensities.size() != n) std::abort();
  if (!s.cloud.times.empty() && s.cloud.times.size() != n) std::abort();
  for (float t : s.cloud.times)
    if (!(t >= 0)) std::abort();
}

inline void read_bag_bytes(BagFormat format, const uint8_t* data, size_t size) {
  static const bool quiet = (spdlog::set_level(spdlog::level::off), true);  // warnings are expected here
  (void)quiet;
  try {
    auto bag = open_bag_bytes(format, std::string(reinterpret_cast<const char*>(data), size), "fuzz.bag");
    for (const BagTopic& topic : bag->topics()) {
      auto cursor = bag->read(topic.name);
      for (BagMessage m; cursor->next(m);) {
        if (!is_pointcloud2_type(topic.type) && !is_livox_type(topic.type)) continue;
        try {
          check_scan(decode_scan(topic, m.data, "fuzz message"));
        } catch (const Error&) {}
      }
    }
  } catch (const Error&) {}
}

}  // namespace gcmap::fuzz
