#pragma once
// Writing ROS bags (for tests, fuzz seeds and the simulator): MCAP (ROS 2 profile, CDR), rosbag2
// sqlite3 folders and ROS 1 v2.0 bags. Written under a temporary name and renamed by close().
#include <cstdint>
#include <memory>
#include <string>
#include <string_view>

#include "gcmap/io/bag_reader.hpp"
#include "gcmap/io/compression.hpp"

namespace gcmap {

struct BagWriterOptions {
  Compression compression = Compression::none;  // MCAP: none, zstd, lz4; ROS 1: none, bz2, lz4; db3: none
  uint64_t chunk_bytes = 1 << 20;               // messages per chunk up to about this many bytes
  bool mcap_summary = true;                     // MCAP: write the summary section and message indexes
  uint64_t db3_messages_per_file = 0;           // db3: split into several files (0: one file)
};

class BagWriter {
 public:
  virtual ~BagWriter() = default;
  // `type` in the ROS 2 spelling ("sensor_msgs/msg/PointCloud2"); a ROS 1 bag stores "sensor_msgs/PointCloud2".
  virtual uint32_t add_topic(const std::string& topic, const std::string& type) = 0;
  // `data` serialized as message_encoding(format) requires; record times in any order (readers sort).
  virtual void write(uint32_t topic, int64_t time_ns, std::string_view data) = 0;
  // Finishes the file (index, summary) and moves it into place. Without close() nothing is left behind.
  virtual void close() = 0;
};

// Encoding the writers store: CDR for MCAP and db3, ROS 1 for .bag.
MessageEncoding message_encoding(BagFormat format);
// `path`: the .mcap / .bag file, or the folder of a db3 bag.
std::unique_ptr<BagWriter> open_bag_writer(const std::string& path, BagFormat format, const BagWriterOptions& options = {});

}  // namespace gcmap
