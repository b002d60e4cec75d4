// ROS 1 bag v2.0 writer: chunks (none, bz2, lz4) each followed by its index data records; at the end
// the connections and chunk infos, located by the bag header (rewritten in place, 4096 bytes).
#include <map>

#include "gcmap/io/bag_bytes.hpp"
#include "gcmap/io/bag_output.hpp"
#include "gcmap/io/bag_writer.hpp"

namespace gcmap::detail {

namespace {

constexpr std::string_view kMagic = "#ROSBAG V2.0\n";
constexpr uint64_t kBagHeaderBytes = 4096;

using Fields = std::vector<std::pair<std::string, std::string>>;

template <typename T>
std::string bin(T v) {
  std::string s;
  put_le(s, v);
  return s;
}

std::string ros_time(int64_t ns) { return bin<uint32_t>(uint32_t(ns / 1000000000)) + bin<uint32_t>(uint32_t(ns % 1000000000)); }

std::string fields(const Fields& f) {
  std::string out;
  for (auto& [k, v] : f) put_str32(out, k + "=" + v);
  return out;
}

std::string record(const Fields& header, std::string_view data) {
  std::string out;
  put_str32(out, fields(header));
  put_str32(out, data);
  return out;
}

class Ros1Writer : public BagWriter {
 public:
  Ros1Writer(const std::string& path, const BagWriterOptions& o) : file_(path), o_(o) {
    if (o.compression == Compression::zstd) throw Error(path + ": a ROS 1 bag has no zstd compression");
    file_.write(kMagic);
    file_.write(bag_header(0));
  }

  uint32_t add_topic(const std::string& topic, const std::string& type) override {
    std::string ros1_type = type;
    if (const size_t p = ros1_type.find("/msg/"); p != std::string::npos) ros1_type.erase(p, 4);
    const uint32_t id = uint32_t(connections_.size());
    const std::string data = fields({{"topic", topic},
                                     {"type", ros1_type},
                                     {"md5sum", message_md5(ros1_type)},
                                     {"message_definition", message_definition(ros1_type)}});
    connections_.push_back(record({{"op", bin<uint8_t>(7)}, {"conn", bin(id)}, {"topic", topic}}, data));
    return id;
  }

  void write(uint32_t conn, int64_t time_ns, std::string_view data) override {
    if (!index_.count(conn)) chunk_ += connections_.at(conn);
    index_[conn].emplace_back(time_ns, uint32_t(chunk_.size()));
    chunk_start_ = in_chunk_ ? std::min(chunk_start_, time_ns) : time_ns;
    chunk_end_ = in_chunk_ ? std::max(chunk_end_, time_ns) : time_ns;
    ++in_chunk_;
    chunk_ += record({{"op", bin<uint8_t>(2)}, {"conn", bin(conn)}, {"time", ros_time(time_ns)}}, data);
    if (chunk_.size() >= o_.chunk_bytes) flush();
  }

  void close() override {
    flush();
    const uint64_t index_pos = file_.pos();
    for (const std::string& c : connections_) file_.write(c);
    for (const std::string& c : chunk_infos_) file_.write(c);
    file_.write_at(kMagic.size(), bag_header(index_pos));
    file_.commit();
  }

 private:
  std::string bag_header(uint64_t index_pos) const {
    const std::string h = fields({{"op", bin<uint8_t>(3)},
                                  {"index_pos", bin(index_pos)},
                                  {"conn_count", bin(uint32_t(connections_.size()))},
                                  {"chunk_count", bin(uint32_t(chunk_infos_.size()))}});
    return bin(uint32_t(h.size())) + h + bin(uint32_t(kBagHeaderBytes - 8 - h.size())) +
           std::string(kBagHeaderBytes - 8 - h.size(), ' ');
  }

  void flush() {
    if (chunk_.empty()) return;
    const char* name = o_.compression == Compression::bz2 ? "bz2" : o_.compression == Compression::lz4 ? "lz4" : "none";
    const uint64_t chunk_at = file_.pos();
    file_.write(record({{"op", bin<uint8_t>(5)}, {"compression", name}, {"size", bin(uint32_t(chunk_.size()))}},
                       compress(o_.compression, chunk_)));
    std::string counts;
    for (auto& [conn, entries] : index_) {
      std::string data;
      for (auto& [t, off] : entries) data += ros_time(t) + bin(off);
      file_.write(record(
          {{"op", bin<uint8_t>(4)}, {"ver", bin<uint32_t>(1)}, {"conn", bin(conn)}, {"count", bin(uint32_t(entries.size()))}},
          data));
      counts += bin(conn) + bin(uint32_t(entries.size()));
    }
    chunk_infos_.push_back(record({{"op", bin<uint8_t>(6)},
                                   {"ver", bin<uint32_t>(1)},
                                   {"chunk_pos", bin(chunk_at)},
                                   {"start_time", ros_time(chunk_start_)},
                                   {"end_time", ros_time(chunk_end_)},
                                   {"count", bin(uint32_t(index_.size()))}},
                                  counts));
    chunk_.clear();
    index_.clear();
    in_chunk_ = 0;
  }

  AtomicFile file_;
  BagWriterOptions o_;
  std::vector<std::string> connections_, chunk_infos_;
  std::string chunk_;
  int64_t chunk_start_ = 0, chunk_end_ = 0;
  uint64_t in_chunk_ = 0;  // messages in the open chunk
  std::map<uint32_t, std::vector<std::pair<int64_t, uint32_t>>> index_;
};

}  // namespace

std::unique_ptr<BagWriter> make_ros1_writer(const std::string& path, const BagWriterOptions& o) {
  return std::make_unique<Ros1Writer>(path, o);
}

}  // namespace gcmap::detail
