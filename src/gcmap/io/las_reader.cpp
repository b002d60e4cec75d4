#include <cstring>

#include "gcmap/core/error.hpp"
#include "gcmap/io/file.hpp"
#include "gcmap/io/las.hpp"

namespace gcmap {
namespace {

constexpr size_t kHeaderSize = 375, kVlrHeaderSize = 54;

class Bytes {
 public:
  Bytes(const std::string& data, const std::string& name) : data_(data), name_(name) {}
  template <typename T>
  T get(size_t at) const {
    need(at, sizeof(T), "header");
    T value;
    std::memcpy(&value, data_.data() + at, sizeof(T));
    return value;
  }
  std::string text(size_t at, size_t width) const {
    need(at, width, "header");
    std::string t = data_.substr(at, width);
    return t.substr(0, t.find('\0'));
  }
  void need(size_t at, size_t n, const char* what) const {
    if (at > data_.size() || n > data_.size() - at)
      throw Error(name_ + ": truncated " + what + " (the file has " + std::to_string(data_.size()) + " bytes)");
  }

 private:
  const std::string& data_;
  const std::string& name_;
};

LasHeader parse_header(const Bytes& b, const std::string& name) {
  if (b.text(0, 4) != "LASF") throw Error(name + ": not a LAS file (no LASF signature)");
  LasHeader h;
  h.version_major = b.get<uint8_t>(24);
  h.version_minor = b.get<uint8_t>(25);
  if (h.version_major != 1 || h.version_minor != 4)
    throw Error(name + ": LAS " + std::to_string(h.version_major) + "." + std::to_string(h.version_minor) + ", only 1.4 is read");
  h.global_encoding = b.get<uint16_t>(6);
  h.system_identifier = b.text(26, 32);
  h.generating_software = b.text(58, 32);
  h.point_format = b.get<uint8_t>(104) & 0x3f;  // the high bits flag compression (LAZ)
  h.record_length = b.get<uint16_t>(105);
  if (b.get<uint8_t>(104) & 0xc0) throw Error(name + ": compressed (LAZ) point data is not read");
  if (h.point_format != 6 && h.point_format != 7)
    throw Error(name + ": point format " + std::to_string(h.point_format) + ", only 6 and 7 are read");
  if (h.record_length < (h.point_format == 6 ? 30 : 36))
    throw Error(name + ": point records of " + std::to_string(h.record_length) + " bytes are too short for their format");
  for (int k = 0; k < 3; ++k) {
    h.scale[k] = b.get<double>(131 + 8 * k);
    h.offset[k] = b.get<double>(155 + 8 * k);
    h.max[k] = b.get<double>(179 + 16 * k);
    h.min[k] = b.get<double>(187 + 16 * k);
  }
  if (!(h.scale.array() > 0).all()) throw Error(name + ": a coordinate scale is not positive");
  h.point_count = b.get<uint64_t>(247);
  for (int r = 0; r < 15; ++r) h.points_by_return[r] = b.get<uint64_t>(255 + 8 * r);
  return h;
}

std::string find_wkt(const Bytes& b, const std::string& name, uint32_t vlrs, size_t header_size) {
  std::string wkt;
  size_t at = header_size;
  for (uint32_t v = 0; v < vlrs; ++v) {
    b.need(at, kVlrHeaderSize, "VLR");
    const uint16_t length = b.get<uint16_t>(at + 20);
    b.need(at + kVlrHeaderSize, length, "VLR");
    if (b.text(at + 2, 16) == "LASF_Projection" && b.get<uint16_t>(at + 18) == 2112) wkt = b.text(at + kVlrHeaderSize, length);
    at += kVlrHeaderSize + length;
  }
  return wkt;
}

void decode(const char* r, const LasHeader& h, LasCloud& c, size_t i) {
  int32_t xyz[3];
  std::memcpy(xyz, r, 12);
  for (int k = 0; k < 3; ++k) c.points[i][k] = xyz[k] * h.scale[k] + h.offset[k];
  std::memcpy(&c.intensities[i], r + 12, 2);
  c.classes[i] = static_cast<uint8_t>(r[16]);
  std::memcpy(&c.point_source_ids[i], r + 20, 2);
  std::memcpy(&c.gps_times[i], r + 22, 8);
  if (h.point_format == 7) std::memcpy(c.colors[i].data(), r + 30, 6);
}

}  // namespace

LasFile parse_las(const std::string& bytes, const std::string& name) {
  const Bytes b(bytes, name);
  LasFile f;
  f.header = parse_header(b, name);
  const size_t data_offset = b.get<uint32_t>(96);
  f.header.wkt = find_wkt(b, name, b.get<uint32_t>(100), b.get<uint16_t>(94));
  const uint64_t n = f.header.point_count;
  const size_t length = f.header.record_length;
  if (data_offset < kHeaderSize || data_offset > bytes.size() || n > (bytes.size() - data_offset) / length)
    throw Error(name + ": truncated: the header promises " + std::to_string(n) + " points of " + std::to_string(length) +
                " bytes");
  LasCloud& c = f.cloud;
  c.points.resize(n);
  c.intensities.resize(n);
  c.classes.resize(n);
  c.point_source_ids.resize(n);
  c.gps_times.resize(n);
  if (f.header.point_format == 7) c.colors.resize(n);
  for (size_t i = 0; i < n; ++i) decode(bytes.data() + data_offset + i * length, f.header, c, i);
  return f;
}

LasFile read_las(const std::string& path) { return parse_las(read_file(path), path); }

}  // namespace gcmap
