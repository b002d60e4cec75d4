#pragma once
// LiDAR scans from ROS bags: PointCloud2 (any field layout) and Livox CustomMsg become a PointCloud
// with intensities and per-point times, plus its stamp.
//
// Stamp convention: when points carry times, the stamp is the earliest point time and `times` are
// seconds after it (all >= 0), whatever the driver's convention; otherwise the header stamp.
// Per-point time fields recognized (first present wins):
//   time_sec + time_nsec  absolute (Luminar)
//   timestamp             float64 absolute s (Hesai, RoboSense); > 1e15: absolute ns (Livox); s after the header
//                         when the first point's value is nearer zero than the header stamp
//   t                     uint32 ns after the header stamp (Ouster); a float type: s
//   time                  float32 s after the header stamp (Velodyne); an integer type: ns
//   offset_time           uint32 ns after the header stamp (Livox); a float type: s
// Points with a non-finite coordinate or time (organized clouds' padding) are dropped.
#include <cstdint>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "gcmap/core/point_cloud.hpp"
#include "gcmap/core/scan_source.hpp"
#include "gcmap/io/bag_reader.hpp"
#include "gcmap/io/bag_writer.hpp"

namespace gcmap {

struct BagScan {
  PointCloud cloud;            // points, intensities (when present), times (s after `stamp`, when present)
  double stamp = 0;            // s since the epoch, see above
  double header_stamp = 0;     // the message header's stamp
  int64_t record_time_ns = 0;  // when the bag recorded it
};

// Throws Error("<where>: ...") for a cloud without x/y/z or whose point_step/row_step/data disagree.
BagScan pointcloud2_to_scan(const PointCloud2Msg& msg, const std::string& where);
BagScan livox_to_scan(const LivoxMsg& msg);
// Decodes one message of a point-cloud topic.
BagScan decode_scan(const BagTopic& topic, std::string_view data, const std::string& where);

// The topics of PointCloud2 or Livox CustomMsg type.
std::vector<std::string> point_cloud_topics(const BagReader& bag);
// `topic` when given (it must be a point-cloud topic), else the single point-cloud topic; throws
// Error listing the candidates when there are none or several.
std::string choose_point_cloud_topic(const BagReader& bag, const std::string& topic);

// What a point-cloud topic holds, from its first message (for bag-info).
struct CloudTopicInfo {
  std::vector<PointField> fields;  // PointCloud2; Livox: x y z reflectivity offset_time
  uint32_t width = 0, height = 0;
  std::string time_field;  // the per-point time used and its convention, or "none"
};
CloudTopicInfo describe_cloud_topic(BagReader& bag, const std::string& topic);

struct BagScanOptions {
  std::string topic;                                          // empty: the single point-cloud topic
  double start_time = 0;                                      // s after the bag's first message
  double duration = std::numeric_limits<double>::infinity();  // s
};

// Streams the scans of one topic in record-time order. A message that cannot be decoded is skipped
// with a warning (counted in skipped()).
class BagScanSource {
 public:
  explicit BagScanSource(const std::string& path, const BagScanOptions& options = {});
  BagScanSource(std::unique_ptr<BagReader> bag, const BagScanOptions& options);

  const BagReader& bag() const { return *bag_; }
  const std::string& topic() const { return topic_; }
  uint64_t message_count() const;  // of the topic in the whole bag
  bool next(BagScan& scan);        // false at the end
  uint64_t skipped() const { return skipped_; }

 private:
  std::unique_ptr<BagReader> bag_;
  std::string topic_;
  std::unique_ptr<MessageCursor> cursor_;
  uint64_t skipped_ = 0;
};

// A bag's point-cloud topic as a scan source for the mapping pipeline: scans [skip, skip + limit)
// of the topic (limit 0: all). Messages are decoded as they are read, in order.
class BagScanRecords : public ScanSource {
 public:
  BagScanRecords(const std::string& path, const BagScanOptions& options, size_t skip = 0, size_t limit = 0);
  std::optional<ScanRecord> next() override;
  size_t size_hint() const override;
  // The bag reader's warnings, and how many messages could not be decoded.
  std::vector<std::string> warnings() const override;
  const BagScanSource& bag() const { return source_; }

 private:
  BagScanSource source_;
  size_t skip_, limit_, given_ = 0;
};

// How scans are written as PointCloud2 (or Livox CustomMsg), to test every reader path.
enum class PointTimeConvention { none, ouster_t, velodyne_time, hesai_timestamp, livox_offset_time, sec_nsec, livox_custom_msg };

struct CloudLayout {
  PointTimeConvention time = PointTimeConvention::ouster_t;
  bool xyz_float64 = false;
  bool intensity = true;
  uint32_t height = 1;           // > 1: organized, cloud.size() a multiple of it, padded point_step/row_step
  bool big_endian_data = false;  // PointCloud2 is_bigendian
  bool big_endian_cdr = false;   // CDR_BE encapsulation (ROS 2 formats)
  float reflectivity_scale = 1;  // Livox CustomMsg: reflectivity = intensity x this, rounded, clamped to 0-255
};

// The serialized message for `cloud` (times in s after `stamp`); the header stamp is `stamp`
// (sec_nsec: the end of the sweep, as Luminar writes it).
std::string encode_scan(const PointCloud& cloud, double stamp, const CloudLayout& layout, MessageEncoding enc);

// Writes scans as one topic of a bag: sensor_msgs/PointCloud2, or Livox CustomMsg as its driver names it
// (ROS 1: livox_ros_driver/CustomMsg, ROS 2: livox_ros_driver2/msg/CustomMsg).
class ScanBagWriter {
 public:
  ScanBagWriter(const std::string& path, BagFormat format, const CloudLayout& layout, const BagWriterOptions& options = {},
                const std::string& topic = "/points");
  // Recorded at the sweep's end (stamp + last point time).
  void write(const PointCloud& cloud, double stamp);
  void close() { writer_->close(); }
  // The bag, for other topics beside the scans (the simulator's /imu).
  BagWriter& writer() { return *writer_; }
  MessageEncoding encoding() const { return encoding_; }

 private:
  std::unique_ptr<BagWriter> writer_;
  CloudLayout layout_;
  MessageEncoding encoding_;
  uint32_t topic_ = 0;
};

}  // namespace gcmap
