#include "gcmap/io/labels.hpp"

#include <bit>
#include <cstring>

#include "gcmap/core/error.hpp"
#include "gcmap/io/file.hpp"

namespace gcmap {

std::vector<uint32_t> parse_labels(std::string_view data, size_t expected_count, const std::string& name) {
  static_assert(std::endian::native == std::endian::little, "labels are little-endian");
  if (data.size() % 4 != 0)
    throw Error(name + ": size " + std::to_string(data.size()) + " is not a multiple of 4 bytes (truncated?)");
  if (data.size() / 4 != expected_count)
    throw Error(name + ": " + std::to_string(data.size() / 4) + " labels for " + std::to_string(expected_count) + " points");
  std::vector<uint32_t> labels(expected_count);
  if (expected_count) std::memcpy(labels.data(), data.data(), data.size());
  return labels;
}

std::vector<uint32_t> read_labels(const std::string& path, size_t expected_count) {
  return parse_labels(read_file(path), expected_count, path);
}

}  // namespace gcmap
