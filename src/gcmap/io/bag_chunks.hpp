#pragma once
// Internal to the bag readers: the time-ordered merge of chunked containers (MCAP, ROS 1).
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "gcmap/io/bag_reader.hpp"

namespace gcmap::detail {

struct ChunkRef {
  uint64_t offset = 0;               // of the chunk record (or of a lone message record)
  int64_t start_ns = 0, end_ns = 0;  // record-time range of its messages
  std::vector<uint32_t> channels;    // channels / connections with messages in it; empty: unknown
  bool lone_message = false;         // an MCAP message record outside any chunk
};

struct PendingMessage {
  int64_t time_ns = 0;
  std::string_view data;
  std::shared_ptr<const std::string> owner;  // the decompressed chunk `data` points into
};

// Appends the messages of one chunk that the cursor wants (any order).
using ChunkLoader = std::function<void(const ChunkRef&, std::vector<PendingMessage>&)>;

// Loads the chunks holding any of `channels` that overlap [begin_ns, end_ns], in order of their start
// time, only as far as needed: a chunk is opened when the earliest pending message is not earlier
// than its start. The loader must filter by channel and time itself.
std::unique_ptr<MessageCursor> merge_chunks(std::vector<ChunkRef> chunks, const std::vector<uint32_t>& channels, int64_t begin_ns,
                                            int64_t end_ns, ChunkLoader load);

// Format readers, for open_bag.
std::unique_ptr<BagReader> open_mcap(std::unique_ptr<class ByteSource> src);
std::unique_ptr<BagReader> open_ros1(std::unique_ptr<class ByteSource> src);
std::unique_ptr<BagReader> open_db3(const std::string& path);
std::unique_ptr<BagReader> open_db3_bytes(std::string bytes, const std::string& name);

// Groups channel ids by topic for BagReader::topics (one entry per topic, counts summed).
struct ChannelInfo {
  uint32_t id = 0;
  std::string topic, type;
  MessageEncoding encoding = MessageEncoding::other;
  uint64_t count = 0;
};
std::vector<BagTopic> group_topics(const std::vector<ChannelInfo>& channels);
std::vector<uint32_t> channels_of(const std::vector<ChannelInfo>& channels, const std::string& topic);
MessageEncoding encoding_from_name(std::string_view name);

}  // namespace gcmap::detail
