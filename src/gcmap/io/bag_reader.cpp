#include "gcmap/io/bag_reader.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <filesystem>

#include "gcmap/core/error.hpp"
#include "gcmap/io/bag_bytes.hpp"
#include "gcmap/io/bag_chunks.hpp"

namespace gcmap {

void BagReader::warn(const std::string& what) {
  spdlog::warn("{}", what);
  warnings_.push_back(what);
}

const char* bag_format_name(BagFormat f) {
  switch (f) {
    case BagFormat::mcap: return "mcap";
    case BagFormat::db3: return "db3";
    case BagFormat::ros1: return "ros1";
  }
  return "?";
}

const BagTopic& BagReader::topic(const std::string& name) const {
  for (const BagTopic& t : topics_)
    if (t.name == name) return t;
  std::string list;
  for (const BagTopic& t : topics_) list += (list.empty() ? "" : ", ") + t.name + " (" + t.type + ")";
  throw Error(path_ + ": no topic " + name + "; topics: " + (list.empty() ? "none" : list));
}

namespace detail {

namespace {

class MergeCursor : public MessageCursor {
 public:
  MergeCursor(std::vector<ChunkRef> chunks, ChunkLoader load) : chunks_(std::move(chunks)), load_(std::move(load)) {}

  bool next(BagMessage& msg) override {
    held_.reset();
    while (next_chunk_ < chunks_.size() && (heap_.empty() || chunks_[next_chunk_].start_ns <= heap_.front().time_ns)) {
      loaded_.clear();
      load_(chunks_[next_chunk_++], loaded_);
      for (PendingMessage& m : loaded_) {
        heap_.push_back({m.time_ns, seq_++, m.data, std::move(m.owner)});
        std::push_heap(heap_.begin(), heap_.end(), later);
      }
    }
    if (heap_.empty()) return false;
    std::pop_heap(heap_.begin(), heap_.end(), later);
    Entry& e = heap_.back();
    msg.time_ns = e.time_ns;
    msg.data = e.data;
    held_ = std::move(e.owner);
    heap_.pop_back();
    return true;
  }

 private:
  struct Entry {
    int64_t time_ns;
    uint64_t seq;  // file order breaks ties
    std::string_view data;
    std::shared_ptr<const std::string> owner;
  };
  static bool later(const Entry& a, const Entry& b) { return a.time_ns != b.time_ns ? a.time_ns > b.time_ns : a.seq > b.seq; }

  std::vector<ChunkRef> chunks_;
  ChunkLoader load_;
  size_t next_chunk_ = 0;
  uint64_t seq_ = 0;
  std::vector<Entry> heap_;
  std::vector<PendingMessage> loaded_;
  std::shared_ptr<const std::string> held_;  // keeps the last returned message alive
};

}  // namespace

std::unique_ptr<MessageCursor> merge_chunks(std::vector<ChunkRef> chunks, const std::vector<uint32_t>& channels, int64_t begin_ns,
                                            int64_t end_ns, ChunkLoader load) {
  auto wanted = [&](const ChunkRef& c) {
    if (c.end_ns < begin_ns || c.start_ns > end_ns) return false;
    if (c.channels.empty()) return true;
    for (uint32_t id : c.channels)
      if (std::find(channels.begin(), channels.end(), id) != channels.end()) return true;
    return false;
  };
  std::erase_if(chunks, [&](const ChunkRef& c) { return !wanted(c); });
  std::stable_sort(chunks.begin(), chunks.end(), [](const ChunkRef& a, const ChunkRef& b) { return a.start_ns < b.start_ns; });
  return std::make_unique<MergeCursor>(std::move(chunks), std::move(load));
}

std::vector<BagTopic> group_topics(const std::vector<ChannelInfo>& channels) {
  std::vector<BagTopic> topics;
  for (const ChannelInfo& c : channels) {
    auto it = std::find_if(topics.begin(), topics.end(), [&](const BagTopic& t) { return t.name == c.topic; });
    if (it == topics.end()) {
      topics.push_back({c.topic, c.type, c.encoding, c.count});
    } else {
      it->message_count += c.count;
    }
  }
  std::sort(topics.begin(), topics.end(), [](const BagTopic& a, const BagTopic& b) { return a.name < b.name; });
  return topics;
}

std::vector<uint32_t> channels_of(const std::vector<ChannelInfo>& channels, const std::string& topic) {
  std::vector<uint32_t> ids;
  for (const ChannelInfo& c : channels)
    if (c.topic == topic) ids.push_back(c.id);
  return ids;
}

MessageEncoding encoding_from_name(std::string_view name) {
  if (name == "cdr") return MessageEncoding::cdr;
  if (name == "ros1") return MessageEncoding::ros1;
  return MessageEncoding::other;
}

}  // namespace detail

namespace {

bool has_extension(const std::string& path, const char* ext) { return std::filesystem::path(path).extension() == ext; }

}  // namespace

bool is_bag_path(const std::string& path) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) return std::filesystem::exists(std::filesystem::path(path) / "metadata.yaml", ec);
  return has_extension(path, ".mcap") || has_extension(path, ".bag") || has_extension(path, ".db3");
}

std::unique_ptr<BagReader> open_bag(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) throw Error(path + ": no such file or folder");
  if (std::filesystem::is_directory(path, ec)) return detail::open_db3(path);
  auto src = open_file_source(path);
  std::string head;
  src->read(0, std::min<uint64_t>(src->size(), 16), head);
  if (head.rfind("\x89MCAP", 0) == 0) return detail::open_mcap(std::move(src));
  if (head.rfind("#ROSBAG V", 0) == 0) return detail::open_ros1(std::move(src));
  if (head.rfind("SQLite format 3", 0) == 0) return detail::open_db3(path);
  throw Error(path + ": not a bag (no MCAP, ROS 1 bag or sqlite3 signature)");
}

std::unique_ptr<BagReader> open_bag_bytes(BagFormat format, std::string bytes, const std::string& name) {
  switch (format) {
    case BagFormat::mcap: return detail::open_mcap(memory_source(std::move(bytes), name));
    case BagFormat::ros1: return detail::open_ros1(memory_source(std::move(bytes), name));
    case BagFormat::db3: return detail::open_db3_bytes(std::move(bytes), name);
  }
  throw Error(name + ": unknown bag format");
}

}  // namespace gcmap
