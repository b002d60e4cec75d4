#pragma once
// The LiDAR messages of ROS bags, decoded without ROS: sensor_msgs/PointCloud2 and Livox CustomMsg
// (livox_ros_driver, livox_ros_driver2), in the ROS 1 serialization (little endian, packed) and in
// ROS 2 CDR (XCDR1, little or big endian, aligned). Malformed messages throw Error("<where>: ...").
#include <array>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace gcmap {

enum class MessageEncoding { ros1, cdr, other };

// sensor_msgs/PointField datatypes.
enum class PointFieldType : uint8_t {
  int8 = 1,
  uint8 = 2,
  int16 = 3,
  uint16 = 4,
  int32 = 5,
  uint32 = 6,
  float32 = 7,
  float64 = 8
};
size_t point_field_size(uint8_t datatype);  // 0 for an unknown datatype
const char* point_field_type_name(uint8_t datatype);

struct PointField {
  std::string name;
  uint32_t offset = 0;
  uint8_t datatype = 0;
  uint32_t count = 1;
};

struct PointCloud2Msg {
  int64_t stamp_ns = 0;  // header stamp
  std::string frame_id;
  uint32_t height = 1, width = 0;
  std::vector<PointField> fields;
  bool is_bigendian = false;
  uint32_t point_step = 0, row_step = 0;
  std::string_view data;  // points, a view into the serialized message (or the caller's buffer)
  bool is_dense = true;
};

PointCloud2Msg decode_pointcloud2(std::string_view msg, MessageEncoding enc, std::string_view where);
std::string encode_pointcloud2(const PointCloud2Msg& m, MessageEncoding enc, bool big_endian_cdr = false);

struct LivoxPoint {
  uint32_t offset_time = 0;  // ns after timebase
  float x = 0, y = 0, z = 0;
  uint8_t reflectivity = 0, tag = 0, line = 0;
};

struct LivoxMsg {
  int64_t stamp_ns = 0;
  std::string frame_id;
  uint64_t timebase = 0;  // ns, absolute
  uint8_t lidar_id = 0;
  std::vector<LivoxPoint> points;
};

LivoxMsg decode_livox(std::string_view msg, MessageEncoding enc, std::string_view where);
std::string encode_livox(const LivoxMsg& m, MessageEncoding enc);

// sensor_msgs/Imu. The covariances are written as unknown (all zero) and not read back.
struct ImuMsg {
  int64_t stamp_ns = 0;  // header stamp
  std::string frame_id;
  std::array<double, 4> orientation{0, 0, 0, 1};  // x y z w
  std::array<double, 3> angular_velocity{};       // rad/s
  std::array<double, 3> linear_acceleration{};    // m/s^2 (the Livox driver: g)
};

ImuMsg decode_imu(std::string_view msg, MessageEncoding enc, std::string_view where);
std::string encode_imu(const ImuMsg& m, MessageEncoding enc);

// sensor_msgs/NavSatFix. The covariance is in the local ENU frame at the fix (east, north, up),
// row major, m^2, as the message defines it.
enum class NavSatStatus : int8_t { unknown = -2, no_fix = -1, fix = 0, sbas_fix = 1, gbas_fix = 2 };
enum class NavSatCovariance : uint8_t { unknown = 0, approximated = 1, diagonal_known = 2, known = 3 };
struct NavSatFixMsg {
  int64_t stamp_ns = 0;  // header stamp
  std::string frame_id;
  NavSatStatus status = NavSatStatus::fix;
  uint16_t service = 1;                              // GPS
  double latitude = 0, longitude = 0, altitude = 0;  // deg, deg, m above the ellipsoid
  std::array<double, 9> position_covariance{};
  NavSatCovariance covariance_type = NavSatCovariance::unknown;
};

NavSatFixMsg decode_navsatfix(std::string_view msg, MessageEncoding enc, std::string_view where);
std::string encode_navsatfix(const NavSatFixMsg& m, MessageEncoding enc);

// Message types as the bags name them (ROS 1 "pkg/Type", ROS 2 "pkg/msg/Type").
bool is_pointcloud2_type(std::string_view type);
bool is_livox_type(std::string_view type);
bool is_imu_type(std::string_view type);
bool is_navsatfix_type(std::string_view type);
// The .msg text (ROS 1 or ROS 2 dependencies, by the spelling of `type`) and the ROS 1 md5sum the
// writers store with a topic of these types.
std::string message_definition(std::string_view type);
std::string message_md5(std::string_view type);

}  // namespace gcmap
