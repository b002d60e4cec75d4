#pragma once
// Reading ROS bags without ROS: ROS 2 MCAP (.mcap) and sqlite3 (.db3 + metadata.yaml, a folder), ROS 1
// (.bag v2.0). Streaming: messages are read chunk by chunk in time order, memory bounded by the chunks
// whose time ranges overlap, whatever the file size. Malformed input throws Error naming the file;
// a truncated file is read as far as it is intact and a chunk with a bad CRC is skipped, with a warning.
#include <cstdint>
#include <limits>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "gcmap/io/ros_messages.hpp"

namespace gcmap {

enum class BagFormat { mcap, db3, ros1 };
const char* bag_format_name(BagFormat f);

struct BagTopic {
  std::string name;
  std::string type;  // as stored: "sensor_msgs/msg/PointCloud2" (ROS 2) or "sensor_msgs/PointCloud2"
  MessageEncoding encoding = MessageEncoding::other;  // how its messages are serialized
  uint64_t message_count = 0;
};

struct BagMessage {
  int64_t time_ns = 0;    // record (log) time, ns since the epoch
  std::string_view data;  // serialized message, valid until the next call of next()
};

class MessageCursor {
 public:
  virtual ~MessageCursor() = default;
  // The next message in record-time order; false at the end.
  virtual bool next(BagMessage& msg) = 0;
};

class BagReader {
 public:
  virtual ~BagReader() = default;
  const std::string& path() const { return path_; }
  BagFormat format() const { return format_; }
  const std::vector<BagTopic>& topics() const { return topics_; }
  // Record times of the first and last message (0, 0 for an empty bag).
  int64_t start_ns() const { return start_ns_; }
  int64_t end_ns() const { return end_ns_; }
  // What was skipped (truncation, chunks with bad CRCs), one line each, as found while opening and reading.
  const std::vector<std::string>& warnings() const { return warnings_; }

  // Throws Error listing the topics when `name` is absent.
  const BagTopic& topic(const std::string& name) const;
  // Messages of one topic with begin_ns <= record time <= end_ns, in record-time order.
  virtual std::unique_ptr<MessageCursor> read(const std::string& topic, int64_t begin_ns = std::numeric_limits<int64_t>::min(),
                                              int64_t end_ns = std::numeric_limits<int64_t>::max()) = 0;

 protected:
  // Logs once and keeps the line for warnings().
  void warn(const std::string& what);
  std::string where(uint64_t offset) const { return path_ + ": record at offset " + std::to_string(offset); }

  std::string path_;
  BagFormat format_ = BagFormat::mcap;
  std::vector<BagTopic> topics_;
  int64_t start_ns_ = 0, end_ns_ = 0;
  std::vector<std::string> warnings_;
};

// By content: MCAP or ROS 1 magic, an sqlite file, or a folder holding metadata.yaml / .db3 files.
std::unique_ptr<BagReader> open_bag(const std::string& path);
// A bag held in memory (tests and fuzzing); `name` stands for the file in messages.
std::unique_ptr<BagReader> open_bag_bytes(BagFormat format, std::string bytes, const std::string& name);
// True when `path` looks like a bag (extension .mcap, .bag, .db3, or a folder with metadata.yaml).
bool is_bag_path(const std::string& path);

}  // namespace gcmap
