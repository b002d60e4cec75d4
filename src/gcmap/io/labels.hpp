#pragma once
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace gcmap {

// SemanticKITTI .label files: one little-endian uint32 per point of the scan, the semantic class in
// the low 16 bits and the instance id in the high 16. Throws Error("PATH: ...") unless the file
// holds exactly `expected_count` labels.
std::vector<uint32_t> read_labels(const std::string& path, size_t expected_count);
// The same on bytes in memory (fuzzed); `name` stands for the path in messages.
std::vector<uint32_t> parse_labels(std::string_view data, size_t expected_count, const std::string& name);

inline uint16_t semantic_class(uint32_t label) { return static_cast<uint16_t>(label & 0xffff); }
// The moving classes of SemanticKITTI (moving-car ... moving-other-vehicle, 252-259).
inline bool is_moving_class(uint32_t label) { return semantic_class(label) >= 252 && semantic_class(label) <= 259; }

}  // namespace gcmap
