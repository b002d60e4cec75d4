#include "gcmap/io/point_cloud_io.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <bit>
#include <cstring>
#include <filesystem>
#include <vector>

#include "gcmap/core/error.hpp"
#include "gcmap/core/preprocess.hpp"
#include "gcmap/io/file.hpp"

namespace gcmap {

namespace {

std::string extension(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext;
}

}  // namespace

PointCloud parse_bin(std::string_view data, BinFields fields, const std::string& path) {
  const size_t stride = fields == BinFields::xyzi ? 16 : 12;
  if (data.empty()) throw Error(path + ": empty file");
  if (data.size() % stride != 0) {
    throw Error(path + ": size " + std::to_string(data.size()) + " is not a multiple of " + std::to_string(stride) +
                " bytes (truncated, or wrong --bin-fields?)");
  }
  const size_t n = data.size() / stride;
  PointCloud cloud;
  cloud.points.resize(n);
  if (fields == BinFields::xyzi) cloud.intensities.resize(n);
  for (size_t i = 0; i < n; ++i) {
    float v[4];
    std::memcpy(v, data.data() + i * stride, stride);
    cloud.points[i] = Eigen::Vector3f(v[0], v[1], v[2]);
    if (fields == BinFields::xyzi) cloud.intensities[i] = v[3];
  }
  return cloud;
}

BinFields parse_bin_fields(const std::string& name) {
  if (name == "xyzi") return BinFields::xyzi;
  if (name == "xyz") return BinFields::xyz;
  throw Error("--bin-fields: expected xyz or xyzi, got '" + name + "'");
}

PointCloud read_point_cloud(const std::string& path, BinFields bin_fields) {
  const std::string ext = extension(path);
  PointCloud cloud;
  if (ext == ".bin") cloud = parse_bin(read_file(path), bin_fields, path);
  else if (ext == ".pcd") cloud = parse_pcd(read_file(path), path);
  else if (ext == ".ply") cloud = parse_ply(read_file(path), path);
  else throw Error(path + ": unknown point cloud format '" + ext + "' (expected .bin, .pcd or .ply)");
  const size_t dropped = remove_non_finite(cloud);
  if (dropped) spdlog::warn("{}: dropped {} non-finite points", path, dropped);
  return cloud;
}

namespace {
// float32 x y z records, then intensity when with_i (0 where the cloud has none), then time when
// with_t (s after the scan's stamp).
void write_records(std::ostream& out, const PointCloud& cloud, bool with_i, bool with_t = false) {
  std::vector<float> buf;
  buf.reserve(cloud.size() * (3 + with_i + with_t));
  for (size_t i = 0; i < cloud.size(); ++i) {
    buf.insert(buf.end(), cloud.points[i].data(), cloud.points[i].data() + 3);
    if (with_i) buf.push_back(cloud.has_intensities() ? cloud.intensities[i] : 0.0f);
    if (with_t) buf.push_back(cloud.times[i]);
  }
  out.write(reinterpret_cast<const char*>(buf.data()), static_cast<std::streamsize>(buf.size() * sizeof(float)));
}

// The optional float fields written after x y z.
std::vector<std::string> extra_fields(const PointCloud& cloud) {
  std::vector<std::string> names;
  if (cloud.has_intensities()) names.push_back("intensity");
  if (cloud.has_times()) names.push_back("time");
  return names;
}
}  // namespace

void write_ply(const std::string& path, const PointCloud& cloud) {
  static_assert(std::endian::native == std::endian::little, "writer assumes a little-endian host");
  write_file_atomic(path, [&](std::ostream& out) {
    out << "ply\nformat binary_little_endian 1.0\ncomment written by gcmap\nelement vertex " << cloud.size()
        << "\nproperty float x\nproperty float y\nproperty float z\n";
    for (const std::string& name : extra_fields(cloud)) out << "property float " << name << "\n";
    out << "end_header\n";
    write_records(out, cloud, cloud.has_intensities(), cloud.has_times());
  });
}

void write_pcd(const std::string& path, const PointCloud& cloud) {
  write_file_atomic(path, [&](std::ostream& out) {
    std::string fields = "x y z", size = "4 4 4", type = "F F F", count = "1 1 1";
    for (const std::string& name : extra_fields(cloud)) fields += " " + name, size += " 4", type += " F", count += " 1";
    out << "# .PCD v0.7 - written by gcmap\nVERSION 0.7\nFIELDS " << fields << "\nSIZE " << size << "\nTYPE " << type
        << "\nCOUNT " << count << "\nWIDTH " << cloud.size() << "\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " << cloud.size()
        << "\nDATA binary\n";
    write_records(out, cloud, cloud.has_intensities(), cloud.has_times());
  });
}

void write_bin(const std::string& path, const PointCloud& cloud, BinFields fields) {
  static_assert(std::endian::native == std::endian::little, "writer assumes a little-endian host");
  write_file_atomic(path, [&](std::ostream& out) { write_records(out, cloud, fields == BinFields::xyzi); });
}

void write_point_cloud(const std::string& path, const PointCloud& cloud, BinFields bin_fields) {
  const std::string ext = extension(path);
  if (ext == ".ply") write_ply(path, cloud);
  else if (ext == ".pcd") write_pcd(path, cloud);
  else if (ext == ".bin") write_bin(path, cloud, bin_fields);
  else throw Error(path + ": cannot write format '" + ext + "' (use .ply, .pcd or .bin)");
}

}  // namespace gcmap
