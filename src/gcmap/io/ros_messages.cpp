#include "gcmap/io/ros_messages.hpp"

#include <array>

#include "gcmap/core/error.hpp"
#include "gcmap/io/bag_bytes.hpp"

namespace gcmap {

namespace {

// ROS 1: packed little endian, strings without terminator. CDR: a 4-byte encapsulation header, then
// every primitive aligned to its size (relative to the end of that header), strings NUL-terminated.
class Deserializer {
 public:
  Deserializer(std::string_view msg, MessageEncoding enc, std::string_view where)
      : r_(msg, std::string(where)), cdr_(enc == MessageEncoding::cdr) {
    if (enc == MessageEncoding::other) r_.fail("unsupported message encoding (neither ros1 nor cdr)");
    if (!cdr_) return;
    const uint8_t b0 = r_.u8(), b1 = r_.u8();
    r_.skip(2);
    if (b0 != 0 || b1 > 1) r_.fail("unknown CDR encapsulation " + std::to_string(b0) + "," + std::to_string(b1));
    swap_ = b1 == 0;  // CDR_BE
  }
  template <typename T>
  T num() {
    align(sizeof(T));
    T v;
    std::memcpy(&v, r_.bytes(sizeof(T)).data(), sizeof(T));
    return swap_ ? byteswap(v) : v;
  }
  std::string_view str() {
    std::string_view s = r_.bytes(num<uint32_t>());
    if (cdr_ && !s.empty() && s.back() == '\0') s.remove_suffix(1);
    return s;
  }
  std::string_view bytes(uint64_t n) { return r_.bytes(n); }
  // An array length, checked against the bytes left (each element takes at least min_bytes).
  uint32_t count(size_t min_bytes) {
    const uint32_t n = num<uint32_t>();
    if (uint64_t(n) * min_bytes > r_.remaining()) r_.fail("array of " + std::to_string(n) + " elements exceeds the message");
    return n;
  }
  int64_t header_stamp(std::string& frame_id) {
    if (!cdr_) num<uint32_t>();  // seq
    const int64_t sec = cdr_ ? int64_t(num<int32_t>()) : int64_t(num<uint32_t>());
    const uint32_t nsec = num<uint32_t>();
    frame_id = std::string(str());
    return sec * 1000000000 + nsec;
  }
  void fail(const std::string& what) const { r_.fail(what); }

 private:
  void align(size_t n) {
    if (cdr_ && r_.pos() > 4) r_.skip((n - (r_.pos() - 4) % n) % n);
  }
  ByteReader r_;
  bool cdr_;
  bool swap_ = false;
};

class Serializer {
 public:
  Serializer(MessageEncoding enc, bool big_endian) : cdr_(enc == MessageEncoding::cdr), swap_(cdr_ && big_endian) {
    if (cdr_) out_ = std::string{0, char(big_endian ? 0 : 1), 0, 0};
  }
  template <typename T>
  void num(T v) {
    if (cdr_) out_.append((sizeof(T) - (out_.size() - 4) % sizeof(T)) % sizeof(T), '\0');
    put_le(out_, swap_ ? byteswap(v) : v);
  }
  void str(std::string_view s) {
    num<uint32_t>(uint32_t(s.size() + cdr_));
    out_.append(s);
    if (cdr_) out_.push_back('\0');
  }
  void bytes(std::string_view s) { out_.append(s); }
  void header(int64_t stamp_ns, const std::string& frame_id) {
    if (!cdr_) num<uint32_t>(0);
    const int64_t sec = stamp_ns >= 0 ? stamp_ns / 1000000000 : (stamp_ns - 999999999) / 1000000000;
    num<int32_t>(int32_t(sec));
    num<uint32_t>(uint32_t(stamp_ns - sec * 1000000000));
    str(frame_id);
  }
  std::string take() { return std::move(out_); }

 private:
  std::string out_;
  bool cdr_, swap_;
};

}  // namespace

size_t point_field_size(uint8_t datatype) {
  static constexpr size_t sizes[] = {0, 1, 1, 2, 2, 4, 4, 4, 8};
  return datatype < 9 ? sizes[datatype] : 0;
}

const char* point_field_type_name(uint8_t datatype) {
  static constexpr const char* names[] = {"?", "int8", "uint8", "int16", "uint16", "int32", "uint32", "float32", "float64"};
  return datatype < 9 ? names[datatype] : "?";
}

PointCloud2Msg decode_pointcloud2(std::string_view msg, MessageEncoding enc, std::string_view where) {
  Deserializer d(msg, enc, where);
  PointCloud2Msg m;
  m.stamp_ns = d.header_stamp(m.frame_id);
  m.height = d.num<uint32_t>();
  m.width = d.num<uint32_t>();
  const uint32_t n = d.count(13);
  m.fields.resize(n);
  for (PointField& f : m.fields) {
    f.name = std::string(d.str());
    f.offset = d.num<uint32_t>();
    f.datatype = d.num<uint8_t>();
    f.count = d.num<uint32_t>();
  }
  m.is_bigendian = d.num<uint8_t>() != 0;
  m.point_step = d.num<uint32_t>();
  m.row_step = d.num<uint32_t>();
  m.data = d.bytes(d.num<uint32_t>());
  m.is_dense = d.num<uint8_t>() != 0;
  return m;
}

std::string encode_pointcloud2(const PointCloud2Msg& m, MessageEncoding enc, bool big_endian_cdr) {
  Serializer s(enc, big_endian_cdr);
  s.header(m.stamp_ns, m.frame_id);
  s.num<uint32_t>(m.height);
  s.num<uint32_t>(m.width);
  s.num<uint32_t>(uint32_t(m.fields.size()));
  for (const PointField& f : m.fields) {
    s.str(f.name);
    s.num<uint32_t>(f.offset);
    s.num<uint8_t>(f.datatype);
    s.num<uint32_t>(f.count);
  }
  s.num<uint8_t>(m.is_bigendian);
  s.num<uint32_t>(m.point_step);
  s.num<uint32_t>(m.row_step);
  s.num<uint32_t>(uint32_t(m.data.size()));
  s.bytes(m.data);
  s.num<uint8_t>(m.is_dense);
  return s.take();
}

LivoxMsg decode_livox(std::string_view msg, MessageEncoding enc, std::string_view where) {
  Deserializer d(msg, enc, where);
  LivoxMsg m;
  m.stamp_ns = d.header_stamp(m.frame_id);
  m.timebase = d.num<uint64_t>();
  d.num<uint32_t>();  // point_num repeats the array length
  m.lidar_id = d.num<uint8_t>();
  d.bytes(3);
  m.points.resize(d.count(19));
  for (LivoxPoint& p : m.points) {
    p.offset_time = d.num<uint32_t>();
    p.x = d.num<float>();
    p.y = d.num<float>();
    p.z = d.num<float>();
    p.reflectivity = d.num<uint8_t>();
    p.tag = d.num<uint8_t>();
    p.line = d.num<uint8_t>();
  }
  return m;
}

std::string encode_livox(const LivoxMsg& m, MessageEncoding enc) {
  Serializer s(enc, false);
  s.header(m.stamp_ns, m.frame_id);
  s.num<uint64_t>(m.timebase);
  s.num<uint32_t>(uint32_t(m.points.size()));
  s.num<uint8_t>(m.lidar_id);
  s.bytes(std::string(3, '\0'));
  s.num<uint32_t>(uint32_t(m.points.size()));
  for (const LivoxPoint& p : m.points) {
    s.num<uint32_t>(p.offset_time);
    s.num<float>(p.x);
    s.num<float>(p.y);
    s.num<float>(p.z);
    s.num<uint8_t>(p.reflectivity);
    s.num<uint8_t>(p.tag);
    s.num<uint8_t>(p.line);
  }
  return s.take();
}

ImuMsg decode_imu(std::string_view msg, MessageEncoding enc, std::string_view where) {
  Deserializer d(msg, enc, where);
  ImuMsg m;
  m.stamp_ns = d.header_stamp(m.frame_id);
  const auto doubles = [&](double* out, int n) {
    for (int k = 0; k < n; ++k) out[k] = d.num<double>();
  };
  std::array<double, 9> covariance;
  doubles(m.orientation.data(), 4);
  doubles(covariance.data(), 9);
  doubles(m.angular_velocity.data(), 3);
  doubles(covariance.data(), 9);
  doubles(m.linear_acceleration.data(), 3);
  doubles(covariance.data(), 9);
  return m;
}

std::string encode_imu(const ImuMsg& m, MessageEncoding enc) {
  Serializer s(enc, false);
  s.header(m.stamp_ns, m.frame_id);
  const auto doubles = [&](const double* v, int n) {
    for (int k = 0; k < n; ++k) s.num<double>(v[k]);
  };
  const std::array<double, 9> unknown{};
  doubles(m.orientation.data(), 4);
  doubles(unknown.data(), 9);
  doubles(m.angular_velocity.data(), 3);
  doubles(unknown.data(), 9);
  doubles(m.linear_acceleration.data(), 3);
  doubles(unknown.data(), 9);
  return s.take();
}

NavSatFixMsg decode_navsatfix(std::string_view msg, MessageEncoding enc, std::string_view where) {
  Deserializer d(msg, enc, where);
  NavSatFixMsg m;
  m.stamp_ns = d.header_stamp(m.frame_id);
  m.status = NavSatStatus(d.num<int8_t>());
  m.service = d.num<uint16_t>();
  m.latitude = d.num<double>();
  m.longitude = d.num<double>();
  m.altitude = d.num<double>();
  for (double& c : m.position_covariance) c = d.num<double>();
  m.covariance_type = NavSatCovariance(d.num<uint8_t>());
  return m;
}

std::string encode_navsatfix(const NavSatFixMsg& m, MessageEncoding enc) {
  Serializer s(enc, false);
  s.header(m.stamp_ns, m.frame_id);
  s.num<int8_t>(int8_t(m.status));
  s.num<uint16_t>(m.service);
  s.num<double>(m.latitude);
  s.num<double>(m.longitude);
  s.num<double>(m.altitude);
  for (double c : m.position_covariance) s.num<double>(c);
  s.num<uint8_t>(uint8_t(m.covariance_type));
  return s.take();
}

bool is_navsatfix_type(std::string_view type) { return type == "sensor_msgs/NavSatFix" || type == "sensor_msgs/msg/NavSatFix"; }

bool is_imu_type(std::string_view type) { return type == "sensor_msgs/Imu" || type == "sensor_msgs/msg/Imu"; }

bool is_pointcloud2_type(std::string_view type) {
  return type == "sensor_msgs/PointCloud2" || type == "sensor_msgs/msg/PointCloud2";
}

bool is_livox_type(std::string_view type) {
  return type == "livox_ros_driver/CustomMsg" || type == "livox_ros_driver2/CustomMsg" ||
         type == "livox_ros_driver/msg/CustomMsg" || type == "livox_ros_driver2/msg/CustomMsg";
}

namespace {

const char* const kRule = "================================================================================\n";

// std_msgs/Header as the definition of a ROS 1 type ("pkg/Type") or a ROS 2 type ("pkg/msg/Type") needs it.
std::string header_definition(bool ros2) {
  if (!ros2) return std::string(kRule) + "MSG: std_msgs/Header\nuint32 seq\ntime stamp\nstring frame_id\n";
  return std::string(kRule) + "MSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n" + kRule +
         "MSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n";
}

}  // namespace

std::string message_definition(std::string_view type) {
  const bool ros2 = type.find("/msg/") != std::string_view::npos;
  if (is_pointcloud2_type(type))
    return "std_msgs/Header header\nuint32 height\nuint32 width\nsensor_msgs/PointField[] fields\nbool is_bigendian\n"
           "uint32 point_step\nuint32 row_step\nuint8[] data\nbool is_dense\n" +
           header_definition(ros2) + kRule +
           "MSG: sensor_msgs/PointField\nuint8 INT8=1\nuint8 UINT8=2\nuint8 INT16=3\nuint8 UINT16=4\nuint8 INT32=5\n"
           "uint8 UINT32=6\nuint8 FLOAT32=7\nuint8 FLOAT64=8\nstring name\nuint32 offset\nuint8 datatype\nuint32 count\n";
  if (is_livox_type(type)) {
    const std::string_view package = type.substr(0, type.find('/'));  // livox_ros_driver or livox_ros_driver2
    return "std_msgs/Header header\nuint64 timebase\nuint32 point_num\nuint8 lidar_id\nuint8[3] rsvd\nCustomPoint[] points\n" +
           header_definition(ros2) + kRule + "MSG: " + std::string(package) +
           "/CustomPoint\nuint32 offset_time\nfloat32 x\nfloat32 y\nfloat32 z\nuint8 reflectivity\nuint8 tag\nuint8 line\n";
  }
  if (is_imu_type(type))
    return "std_msgs/Header header\ngeometry_msgs/Quaternion orientation\nfloat64[9] orientation_covariance\n"
           "geometry_msgs/Vector3 angular_velocity\nfloat64[9] angular_velocity_covariance\n"
           "geometry_msgs/Vector3 linear_acceleration\nfloat64[9] linear_acceleration_covariance\n" +
           header_definition(ros2) + kRule + "MSG: geometry_msgs/Quaternion\nfloat64 x\nfloat64 y\nfloat64 z\nfloat64 w\n" +
           kRule + "MSG: geometry_msgs/Vector3\nfloat64 x\nfloat64 y\nfloat64 z\n";
  if (is_navsatfix_type(type))
    return "std_msgs/Header header\nsensor_msgs/NavSatStatus status\nfloat64 latitude\nfloat64 longitude\nfloat64 altitude\n"
           "float64[9] position_covariance\nuint8 COVARIANCE_TYPE_UNKNOWN=0\nuint8 COVARIANCE_TYPE_APPROXIMATED=1\n"
           "uint8 COVARIANCE_TYPE_DIAGONAL_KNOWN=2\nuint8 COVARIANCE_TYPE_KNOWN=3\nuint8 position_covariance_type\n" +
           header_definition(ros2) + kRule +
           "MSG: sensor_msgs/NavSatStatus\nint8 STATUS_NO_FIX=-1\nint8 STATUS_FIX=0\nint8 STATUS_SBAS_FIX=1\n"
           "int8 STATUS_GBAS_FIX=2\nint8 status\nuint16 SERVICE_GPS=1\nuint16 SERVICE_GLONASS=2\nuint16 SERVICE_COMPASS=4\n"
           "uint16 SERVICE_GALILEO=8\nuint16 service\n";
  return "";
}

std::string message_md5(std::string_view type) {
  // ROS 1 md5sums (genmsg): the same for both Livox drivers, whose definitions are identical.
  if (is_pointcloud2_type(type)) return "1158d486dd51d683ce2f1be655c3c181";
  if (is_livox_type(type)) return "e4d6829bdfe657cb6c21a746c86b21a6";
  if (is_imu_type(type)) return "6a62c6daae103f4ff57a132d6f95cec2";
  if (is_navsatfix_type(type)) return "2d3a8cd499b9b4a0249fb98fd05cfa48";
  return "*";
}

}  // namespace gcmap
