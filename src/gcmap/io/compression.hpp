#pragma once
// Chunk compression of the bag containers: zstd and LZ4 frames (MCAP, ROS 1 lz4, rosbag2 message
// compression) and bzip2 (ROS 1).
#include <cstdint>
#include <string>
#include <string_view>

namespace gcmap {

enum class Compression { none, zstd, lz4, bz2 };

// The output grows only as data is actually produced, so a header that lies about the size cannot
// make us allocate it. Throws Error("<where>: ...") on corrupt input or when the output would exceed
// `max_size` (`exact`: the output must be exactly max_size bytes).
void decompress(Compression c, std::string_view in, uint64_t max_size, bool exact, std::string& out, const std::string& where);

std::string compress(Compression c, std::string_view in);

}  // namespace gcmap
