// MCAP writer, ROS 2 profile: schemas (ros2msg) and channels (cdr) in the data section, messages in
// chunks, optionally message indexes and a summary (schemas, channels, statistics, chunk indexes).
#include <map>

#include "gcmap/io/bag_bytes.hpp"
#include "gcmap/io/bag_output.hpp"
#include "gcmap/io/bag_writer.hpp"

namespace gcmap::detail {

namespace {

constexpr std::string_view kMagic("\x89MCAP0\r\n", 8);

std::string record(uint8_t op, std::string_view body) {
  std::string r;
  put_u8(r, op);
  put_le<uint64_t>(r, body.size());
  r.append(body);
  return r;
}

std::string u16_u64_map(const std::map<uint16_t, uint64_t>& m) {
  std::string body;
  for (auto& [k, v] : m) {
    put_le<uint16_t>(body, k);
    put_le<uint64_t>(body, v);
  }
  std::string out;
  put_str32(out, body);
  return out;
}

class McapWriter : public BagWriter {
 public:
  McapWriter(const std::string& path, const BagWriterOptions& o) : file_(path), o_(o) {
    if (o.compression == Compression::bz2) throw Error(path + ": MCAP has no bz2 compression");
    std::string header;
    put_str32(header, "ros2");
    put_str32(header, "gcmap");
    file_.write(kMagic);
    file_.write(record(1, header));
  }

  uint32_t add_topic(const std::string& topic, const std::string& type) override {
    const uint16_t id = uint16_t(channels_.size());
    std::string schema, channel;
    put_le<uint16_t>(schema, id + 1);
    put_str32(schema, type);
    put_str32(schema, "ros2msg");
    put_str32(schema, message_definition(type));
    put_le<uint16_t>(channel, id);
    put_le<uint16_t>(channel, id + 1);
    put_str32(channel, topic);
    put_str32(channel, "cdr");
    put_le<uint32_t>(channel, 0);  // no metadata
    channels_.push_back(record(4, channel));
    schemas_.push_back(record(3, schema));
    file_.write(schemas_.back());
    file_.write(channels_.back());
    return id;
  }

  void write(uint32_t topic, int64_t time_ns, std::string_view data) override {
    std::string body;
    put_le<uint16_t>(body, uint16_t(topic));
    put_le<uint32_t>(body, uint32_t(count_));
    put_le<uint64_t>(body, uint64_t(time_ns));
    put_le<uint64_t>(body, uint64_t(time_ns));
    body.append(data);
    chunk_start_ = chunk_.empty() ? time_ns : std::min(chunk_start_, time_ns);
    chunk_end_ = chunk_.empty() ? time_ns : std::max(chunk_end_, time_ns);
    start_ = count_ ? std::min(start_, time_ns) : time_ns;
    end_ = count_ ? std::max(end_, time_ns) : time_ns;
    index_[uint16_t(topic)].emplace_back(time_ns, chunk_.size());
    ++counts_[uint16_t(topic)];
    ++count_;
    chunk_ += record(5, body);
    if (chunk_.size() >= o_.chunk_bytes) flush();
  }

  void close() override {
    flush();
    std::string data_end;
    put_le<uint32_t>(data_end, 0);
    file_.write(record(15, data_end));
    uint64_t summary_start = 0;
    if (o_.mcap_summary) {
      summary_start = file_.pos();
      for (size_t i = 0; i < channels_.size(); ++i) file_.write(schemas_[i] + channels_[i]);
      std::string stats;
      put_le<uint64_t>(stats, count_);
      put_le<uint16_t>(stats, uint16_t(schemas_.size()));
      put_le<uint32_t>(stats, uint32_t(channels_.size()));
      put_le<uint32_t>(stats, 0);
      put_le<uint32_t>(stats, 0);
      put_le<uint32_t>(stats, uint32_t(chunk_indexes_.size()));
      put_le<uint64_t>(stats, uint64_t(count_ ? start_ : 0));
      put_le<uint64_t>(stats, uint64_t(count_ ? end_ : 0));
      stats += u16_u64_map(counts_);
      file_.write(record(11, stats));
      for (const std::string& c : chunk_indexes_) file_.write(c);
    }
    std::string footer;
    put_le<uint64_t>(footer, summary_start);
    put_le<uint64_t>(footer, 0);
    put_le<uint32_t>(footer, 0);
    file_.write(record(2, footer));
    file_.write(kMagic);
    file_.commit();
  }

 private:
  void flush() {
    if (chunk_.empty()) return;
    const std::string packed = compress(o_.compression, chunk_);
    std::string body;
    put_le<uint64_t>(body, uint64_t(chunk_start_));
    put_le<uint64_t>(body, uint64_t(chunk_end_));
    put_le<uint64_t>(body, chunk_.size());
    put_le<uint32_t>(body, crc32(chunk_));
    put_str32(body, o_.compression == Compression::zstd ? "zstd" : o_.compression == Compression::lz4 ? "lz4" : "");
    put_le<uint64_t>(body, packed.size());
    body += packed;
    const uint64_t chunk_at = file_.pos();
    file_.write(record(6, body));
    const uint64_t chunk_len = file_.pos() - chunk_at;
    std::map<uint16_t, uint64_t> index_offsets;
    if (o_.mcap_summary) {
      for (auto& [ch, entries] : index_) {
        std::string mi, list;
        put_le<uint16_t>(mi, ch);
        for (auto& [t, off] : entries) {
          put_le<uint64_t>(list, uint64_t(t));
          put_le<uint64_t>(list, off);
        }
        put_str32(mi, list);
        index_offsets[ch] = file_.pos();
        file_.write(record(7, mi));
      }
    }
    std::string ci;
    put_le<uint64_t>(ci, uint64_t(chunk_start_));
    put_le<uint64_t>(ci, uint64_t(chunk_end_));
    put_le<uint64_t>(ci, chunk_at);
    put_le<uint64_t>(ci, chunk_len);
    ci += u16_u64_map(index_offsets);
    put_le<uint64_t>(ci, file_.pos() - chunk_at - chunk_len);
    put_str32(ci, o_.compression == Compression::zstd ? "zstd" : o_.compression == Compression::lz4 ? "lz4" : "");
    put_le<uint64_t>(ci, packed.size());
    put_le<uint64_t>(ci, chunk_.size());
    chunk_indexes_.push_back(record(8, ci));
    chunk_.clear();
    index_.clear();
  }

  AtomicFile file_;
  BagWriterOptions o_;
  std::vector<std::string> schemas_, channels_, chunk_indexes_;
  std::string chunk_;
  int64_t chunk_start_ = 0, chunk_end_ = 0, start_ = 0, end_ = 0;
  std::map<uint16_t, std::vector<std::pair<int64_t, uint64_t>>> index_;
  std::map<uint16_t, uint64_t> counts_;
  uint64_t count_ = 0;
};

}  // namespace

std::unique_ptr<BagWriter> make_mcap_writer(const std::string& path, const BagWriterOptions& o) {
  return std::make_unique<McapWriter>(path, o);
}

}  // namespace gcmap::detail
