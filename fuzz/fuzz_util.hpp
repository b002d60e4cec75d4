#pragma once
// Shared by the libFuzzer targets: a reader may only answer bad bytes with gcmap::Error; any other
// exception escapes LLVMFuzzerTestOneInput and libFuzzer reports it as a crash.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string_view>

#include "gcmap/core/point_cloud.hpp"

namespace gcmap::fuzz {

inline std::string_view bytes(const uint8_t* data, size_t size) { return {reinterpret_cast<const char*>(data), size}; }

// A parsed cloud must be self-consistent (intensities absent or one per point).
inline void check_cloud(const PointCloud& cloud) {
  if (!cloud.intensities.empty() && cloud.intensities.size() != cloud.points.size()) std::abort();
}

}  // namespace gcmap::fuzz
