// PointCloud2 / Livox CustomMsg <-> PointCloud with per-point times (conventions in bag_scans.hpp).
#include <algorithm>
#include <cmath>

#include "gcmap/core/error.hpp"
#include "gcmap/io/bag_bytes.hpp"
#include "gcmap/io/bag_scans.hpp"

namespace gcmap {

namespace {

struct FieldReader {
  const PointField* field = nullptr;
  bool swap = false;

  explicit operator bool() const { return field != nullptr; }
  template <typename T>
  T load(const char* p) const {
    T v;
    std::memcpy(&v, p + field->offset, sizeof(T));
    return swap ? byteswap(v) : v;
  }
  double operator()(const char* p) const {
    switch (PointFieldType(field->datatype)) {
      case PointFieldType::int8: return load<int8_t>(p);
      case PointFieldType::uint8: return load<uint8_t>(p);
      case PointFieldType::int16: return load<int16_t>(p);
      case PointFieldType::uint16: return load<uint16_t>(p);
      case PointFieldType::int32: return load<int32_t>(p);
      case PointFieldType::uint32: return load<uint32_t>(p);
      case PointFieldType::float32: return load<float>(p);
      case PointFieldType::float64: return load<double>(p);
    }
    return 0;
  }
  bool is_float() const { return field->datatype >= uint8_t(PointFieldType::float32); }
};

FieldReader find_field(const PointCloud2Msg& m, const char* name, const std::string& where) {
  for (const PointField& f : m.fields) {
    if (f.name != name) continue;
    const size_t size = point_field_size(f.datatype);
    if (size == 0) throw Error(where + ": field " + f.name + " has unknown datatype " + std::to_string(f.datatype));
    if (uint64_t(f.offset) + size > m.point_step) throw Error(where + ": field " + f.name + " lies outside point_step");
    return {&f, m.is_bigendian};
  }
  return {};
}

enum class TimeKind { none, relative, absolute, sec_nsec };

struct TimeSpec {
  TimeKind kind = TimeKind::none;
  FieldReader a, b;
  double scale = 1;  // to seconds
};

// Divided, not multiplied by 1e-9: the nearest double, as a stamp read from text is.
double ns_to_s(int64_t ns) { return double(ns) / 1e9; }

// `first` is a point of the message: its `timestamp` is absolute when nearer the header stamp than
// zero (this also holds for simulated clocks that start at 0).
TimeSpec find_time(const PointCloud2Msg& m, const char* first, const std::string& where) {
  TimeSpec s;
  if ((s.a = find_field(m, "time_sec", where)) && (s.b = find_field(m, "time_nsec", where))) {
    s.kind = TimeKind::sec_nsec;
  } else if ((s.a = find_field(m, "timestamp", where))) {
    const double v = first ? s.a(first) : 0;
    s.scale = std::abs(v) > 1e15 ? 1e-9 : 1;
    const bool near_header = std::abs(v * s.scale - ns_to_s(m.stamp_ns)) < std::abs(v * s.scale);
    s.kind = near_header ? TimeKind::absolute : TimeKind::relative;
  } else {
    for (const char* name : {"t", "time", "offset_time"}) {
      if (!(s.a = find_field(m, name, where))) continue;
      s.kind = TimeKind::relative;
      s.scale = s.a.is_float() ? 1 : 1e-9;
      break;
    }
  }
  return s;
}

void check_layout(const PointCloud2Msg& m, const std::string& where) {
  const uint64_t n = uint64_t(m.height) * m.width;
  if (n == 0) return;
  if (m.point_step == 0) throw Error(where + ": point_step is 0");
  if (uint64_t(m.width) * m.point_step > m.row_step)
    throw Error(where + ": row_step " + std::to_string(m.row_step) + " < width * point_step");
  if (uint64_t(m.height - 1) * m.row_step + uint64_t(m.width) * m.point_step > m.data.size())
    throw Error(where + ": data holds " + std::to_string(m.data.size()) + " bytes, fewer than height * row_step");
}

// Sets stamp and times (s after the earliest point) from the times relative to the header.
void finish_times(BagScan& scan, const std::vector<double>& rel) {
  if (rel.empty()) return;
  const double t0 = *std::min_element(rel.begin(), rel.end());
  scan.stamp = scan.header_stamp + t0;
  scan.cloud.times.resize(rel.size());
  for (size_t i = 0; i < rel.size(); ++i) scan.cloud.times[i] = float(rel[i] - t0);
}

}  // namespace

BagScan pointcloud2_to_scan(const PointCloud2Msg& m, const std::string& where) {
  check_layout(m, where);
  const FieldReader x = find_field(m, "x", where), y = find_field(m, "y", where), z = find_field(m, "z", where);
  if (!x || !y || !z) throw Error(where + ": PointCloud2 without x, y and z fields");
  FieldReader intensity = find_field(m, "intensity", where);
  if (!intensity) intensity = find_field(m, "reflectivity", where);
  const char* first = m.height && m.width ? m.data.data() : nullptr;
  const TimeSpec time = find_time(m, first, where);

  BagScan scan;
  scan.header_stamp = ns_to_s(m.stamp_ns);
  scan.stamp = scan.header_stamp;
  const size_t n = size_t(m.height) * m.width;
  scan.cloud.points.reserve(n);
  if (intensity) scan.cloud.intensities.reserve(n);
  std::vector<double> rel;
  if (time.kind != TimeKind::none) rel.reserve(n);
  // Whole seconds apart, so that sec/nsec times subtract exactly in double.
  const double header_sec = double(m.stamp_ns / 1000000000), header_nsec = double(m.stamp_ns % 1000000000);
  for (uint32_t row = 0; row < (m.width ? m.height : 0); ++row) {
    const char* p = m.data.data() + uint64_t(row) * m.row_step;
    for (uint32_t col = 0; col < m.width; ++col, p += m.point_step) {
      const Eigen::Vector3f pt(float(x(p)), float(y(p)), float(z(p)));
      if (!pt.allFinite()) continue;
      double t = 0;
      if (time.kind == TimeKind::relative) t = time.a(p) * time.scale;
      if (time.kind == TimeKind::absolute) t = time.a(p) * time.scale - scan.header_stamp;
      if (time.kind == TimeKind::sec_nsec) t = (time.a(p) - header_sec) + (time.b(p) - header_nsec) * 1e-9;
      if (!std::isfinite(t)) continue;
      scan.cloud.points.push_back(pt);
      if (intensity) scan.cloud.intensities.push_back(float(intensity(p)));
      if (time.kind != TimeKind::none) rel.push_back(t);
    }
  }
  finish_times(scan, rel);
  return scan;
}

BagScan livox_to_scan(const LivoxMsg& m) {
  BagScan scan;
  scan.header_stamp = ns_to_s(m.stamp_ns);
  scan.stamp = scan.header_stamp;
  std::vector<double> rel;
  rel.reserve(m.points.size());
  for (const LivoxPoint& p : m.points) {
    const Eigen::Vector3f pt(p.x, p.y, p.z);
    if (!pt.allFinite()) continue;
    scan.cloud.points.push_back(pt);
    scan.cloud.intensities.push_back(p.reflectivity);
    rel.push_back(double(int64_t(m.timebase + p.offset_time - uint64_t(m.stamp_ns))) * 1e-9);  // modular: no overflow
  }
  finish_times(scan, rel);
  return scan;
}

CloudTopicInfo describe_cloud_topic(BagReader& bag, const std::string& topic) {
  const BagTopic& t = bag.topic(topic);
  CloudTopicInfo info;
  BagMessage msg;
  const auto cursor = bag.read(topic);  // msg.data views the cursor's buffer: keep it alive
  if (!cursor->next(msg)) return info;
  const std::string where = bag.path() + ": first message of " + topic;
  if (is_livox_type(t.type)) {
    const LivoxMsg m = decode_livox(msg.data, t.encoding, where);
    info.width = uint32_t(m.points.size());
    info.height = 1;
    info.fields = {{"x", 4, 7, 1}, {"y", 8, 7, 1}, {"z", 12, 7, 1}, {"reflectivity", 16, 2, 1}, {"offset_time", 0, 6, 1}};
    info.time_field = "offset_time (ns after timebase)";
    return info;
  }
  const PointCloud2Msg m = decode_pointcloud2(msg.data, t.encoding, where);
  check_layout(m, where);
  info.fields = m.fields;
  info.width = m.width;
  info.height = m.height;
  const TimeSpec s = find_time(m, m.height && m.width ? m.data.data() : nullptr, where);
  const std::string unit = s.scale == 1 ? "s" : "ns";
  switch (s.kind) {
    case TimeKind::none: info.time_field = "none"; break;
    case TimeKind::sec_nsec: info.time_field = "time_sec + time_nsec (absolute)"; break;
    case TimeKind::absolute: info.time_field = s.a.field->name + " (absolute " + unit + ")"; break;
    case TimeKind::relative: info.time_field = s.a.field->name + " (" + unit + " after the header stamp)"; break;
  }
  return info;
}

BagScan decode_scan(const BagTopic& topic, std::string_view data, const std::string& where) {
  if (is_livox_type(topic.type)) return livox_to_scan(decode_livox(data, topic.encoding, where));
  if (!is_pointcloud2_type(topic.type)) throw Error(where + ": type " + topic.type + " is not a point cloud");
  return pointcloud2_to_scan(decode_pointcloud2(data, topic.encoding, where), where);
}

}  // namespace gcmap
