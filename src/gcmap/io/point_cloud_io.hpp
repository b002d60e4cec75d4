#pragma once
#include <string>
#include <string_view>

#include "gcmap/core/point_cloud.hpp"

namespace gcmap {

// Layout of raw .bin scans: KITTI float32 x y z intensity, or plain float32 x y z.
enum class BinFields { xyzi, xyz };
BinFields parse_bin_fields(const std::string& name);

// Reads .bin, .pcd (ascii, binary, binary_compressed) or .ply (ascii, binary little/big endian) by
// extension. Fields are found by name in any order; x, y, z are required, intensity is optional.
// Non-finite points are dropped (counted in the log). Malformed input throws Error("PATH: ...").
PointCloud read_point_cloud(const std::string& path, BinFields bin_fields = BinFields::xyzi);

// Binary PLY / binary PCD with x y z, then intensity and time (float32, s after the scan's stamp)
// when present, written atomically. The readers take x y z and intensity.
void write_ply(const std::string& path, const PointCloud& cloud);
void write_pcd(const std::string& path, const PointCloud& cloud);
// Raw float32 records in the given layout (intensity 0 where the cloud has none), written atomically.
void write_bin(const std::string& path, const PointCloud& cloud, BinFields fields = BinFields::xyzi);
void write_point_cloud(const std::string& path, const PointCloud& cloud, BinFields bin_fields = BinFields::xyzi);  // by extension

// The parsers behind read_point_cloud, on bytes in memory (fuzzed): `name` stands for the path in
// messages. They keep non-finite points; read_point_cloud drops them.
PointCloud parse_bin(std::string_view data, BinFields fields, const std::string& name);
PointCloud parse_pcd(std::string_view data, const std::string& name);
PointCloud parse_ply(std::string_view data, const std::string& name);

// LZF as used by PCD binary_compressed. Throws on corrupt input.
std::string lzf_decompress(std::string_view in, size_t expected_size);

}  // namespace gcmap
