#pragma once
// A simulated drive on disk: the KITTI layout, or a ROS bag with the ground truth beside it, so that
// every bag reader is tested on data the project makes itself.
#include <optional>
#include <string>

#include "gcmap/io/bag_scans.hpp"
#include "gcmap/sim/gnss.hpp"
#include "gcmap/sim/imu.hpp"
#include "gcmap/sim/simulator.hpp"

namespace gcmap::sim {

// The message type of a bag's scans.
enum class ScanMessage { pointcloud2, livox_custom_msg };

// The per-point time mistakes real recordings make, written on purpose so that `gcmap inspect`
// and `gcmap map` are tested on each: times in ms or ns where s are expected, absolute times (s
// on a clock started 1000 s before the drive) where times after the stamp are expected, the stamp at the end of the
// sweep (times.txt or the header; times before it), times all zero.
enum class TimeMistake { none, milliseconds, nanoseconds, absolute, sweep_end, zero };

struct OutputOptions {
  std::optional<BagFormat> bag;  // none: the KITTI layout
  // livox_custom_msg (bags only): livox_ros_driver/CustomMsg in a ROS 1 bag, livox_ros_driver2/msg/CustomMsg
  // in mcap and db3; timebase the stamp, offset_time in ns, reflectivity = round(255 x intensity); `time` unused.
  ScanMessage message = ScanMessage::pointcloud2;
  // The per-point time field of the bag's PointCloud2 (when the drive has motion distortion):
  // ouster_t, velodyne_time, hesai_timestamp or livox_offset_time.
  PointTimeConvention time = PointTimeConvention::ouster_t;
  Compression compression = Compression::none;  // mcap: zstd, lz4; ros1: bz2, lz4
  // Also an IMU (sim/imu.hpp): imu.txt and imu_bias.txt in DIR, and a bag's /imu topic
  // (sensor_msgs/Imu; with livox_custom_msg the acceleration in g, as the Livox driver writes it).
  std::optional<ImuSimConfig> imu;
  // Also GNSS fixes (sim/gnss.hpp): gnss.txt in DIR, beside the scans or the bag; scenario.json
  // gives the world's geodetic origin (poses_world.txt is local ENU there) and the receiver model.
  std::optional<GnssSimConfig> gnss;
  // Needs motion distortion; other than zero, a float time: the KITTI layout's point_times/ or velodyne.
  TimeMistake mistake = TimeMistake::none;
};

// "kitti", "mcap", "db3" or "bag" (ROS 1); Error naming `key` otherwise.
std::optional<BagFormat> parse_output_format(const std::string& text, const std::string& key);
// "ouster", "velodyne", "hesai" or "livox".
PointTimeConvention parse_time_field(const std::string& text, const std::string& key);
// "none", "ms", "ns", "absolute", "sweep_end" or "zero".
TimeMistake parse_time_mistake(const std::string& text, const std::string& key);
// "pointcloud2" or "livox".
ScanMessage parse_scan_message(const std::string& text, const std::string& key);
// "none", "zstd", "lz4" or "bz2", checked against what `bag` can hold.
Compression parse_compression(const std::string& text, std::optional<BagFormat> bag, const std::string& key);

// The bag inside DIR: DIR/drive.mcap, DIR/drive.bag, or the rosbag2 folder DIR/drive.
std::string simulated_bag_path(const std::string& dir, BagFormat format);

// As write_simulation (simulator.hpp) for the KITTI layout. For a bag: one /points topic of
// sensor_msgs/PointCloud2 (x, y, z, intensity float32 and the chosen time field) or of Livox
// CustomMsg (Error for the KITTI layout), header stamps the
// stamps of times.txt (the start of each sweep, 0.1 s apart from 0), recorded at the end of each
// sweep; poses.txt, times.txt, scenario.json and labels/ in DIR beside the bag.
size_t write_simulation(const std::string& dir, const SimulationConfig& config, const OutputOptions& output, bool quiet = true);

}  // namespace gcmap::sim
