// MCAP (https://mcap.dev/spec): magic, records <opcode u8><length u64><body>, optional summary
// section (schemas, channels, chunk indexes, statistics) located by the footer.

#include <algorithm>
#include <map>
#include <optional>

#include "gcmap/core/error.hpp"
#include "gcmap/io/bag_bytes.hpp"
#include "gcmap/io/bag_chunks.hpp"
#include "gcmap/io/compression.hpp"

namespace gcmap::detail {

namespace {

constexpr std::string_view kMagic("\x89MCAP0\r\n", 8);
enum Op : uint8_t {
  kSchema = 3,
  kChannel = 4,
  kMessage = 5,
  kChunk = 6,
  kChunkIndex = 8,
  kStatistics = 11,
  kDataEnd = 15,
  kFooter = 2
};
constexpr uint64_t kMaxChunkBytes = uint64_t(1) << 32;
constexpr uint64_t kFooterRecord = 1 + 8 + 20;

// Calls f(opcode, body, offset of the record within `records`) for each record.
template <typename F>
void for_each_record(std::string_view records, const std::string& where, F&& f) {
  ByteReader r(records, where);
  while (!r.done()) {
    const size_t at = r.pos();
    const uint8_t op = r.u8();
    const uint64_t len = r.u64();
    f(op, r.bytes(len), at);
  }
}

class McapReader : public BagReader {
 public:
  explicit McapReader(std::unique_ptr<ByteSource> src) : src_(std::move(src)) {
    path_ = src_->name();
    format_ = BagFormat::mcap;
    std::string head;
    if (src_->size() < kMagic.size()) throw Error(path_ + ": too short for an MCAP file");
    src_->read(0, kMagic.size(), head);
    if (head != kMagic) throw Error(path_ + ": not an MCAP file (bad magic)");
    if (!read_summary()) scan_linear();
    for (auto& [id, c] : channels_) infos_.push_back(c);
    topics_ = group_topics(infos_);
  }

  std::unique_ptr<MessageCursor> read(const std::string& name, int64_t begin_ns, int64_t end_ns) override {
    topic(name);
    std::vector<uint32_t> ids = channels_of(infos_, name);
    auto load = [this, ids, begin_ns, end_ns](const ChunkRef& c, std::vector<PendingMessage>& out) {
      auto buf = std::make_shared<std::string>();
      std::optional<std::string_view> records;
      if (c.lone_message) {
        load_record(c.offset, *buf);
        records = *buf;
      } else {
        records = load_chunk(c.offset, *buf);
      }
      if (!records) return;
      for_each_record(*records, where(c.offset), [&](uint8_t op, std::string_view body, size_t) {
        if (op != kMessage) return;
        ByteReader r(body, where(c.offset));
        const uint16_t ch = r.u16();
        r.u32();
        const int64_t t = int64_t(r.u64());
        r.u64();
        if (t < begin_ns || t > end_ns || std::find(ids.begin(), ids.end(), ch) == ids.end()) return;
        out.push_back({t, body.substr(r.pos()), buf});
      });
    };
    return merge_chunks(chunks_, ids, begin_ns, end_ns, load);
  }

 private:
  // The record at `offset` (opcode and length header included).
  void load_record(uint64_t offset, std::string& out) const {
    std::string head;
    src_->read(offset, 9, head);
    ByteReader r(head, where(offset));
    r.u8();
    const uint64_t len = r.u64();
    if (len > src_->size() - offset - 9) r.fail("length " + std::to_string(len) + " runs past the end of the file");
    src_->read(offset, 9 + len, out);
  }

  // The records of the chunk at `offset`, a view into `out` (uncompressed chunks are used in place);
  // nullopt (with a warning) on a CRC mismatch.
  std::optional<std::string_view> load_chunk(uint64_t offset, std::string& out) {
    std::string packed;
    load_record(offset, packed);
    const std::string at = where(offset);
    ByteReader r(packed, at);
    if (r.u8() != kChunk) r.fail("expected a chunk record");
    r.u64();
    r.skip(16);
    const uint64_t usize = r.u64();
    const uint32_t crc = r.u32();
    const std::string_view comp = r.str32();
    const std::string_view data = r.bytes(r.u64());
    if (usize > kMaxChunkBytes) r.fail("chunk of " + std::to_string(usize) + " bytes is implausibly large");
    Compression c = Compression::none;
    if (comp == "zstd") c = Compression::zstd;
    else if (comp == "lz4") c = Compression::lz4;
    else if (!comp.empty()) r.fail("unknown compression '" + std::string(comp) + "'");
    std::string_view records;
    if (c == Compression::none) {
      if (data.size() != usize)
        r.fail("chunk holds " + std::to_string(data.size()) + " bytes, declares " + std::to_string(usize));
      const size_t from = size_t(data.data() - packed.data());
      out = std::move(packed);
      records = std::string_view(out).substr(from, usize);
    } else {
      decompress(c, data, usize, true, out, at);
      records = out;
    }
    if (crc != 0 && crc32(records) != crc) {
      warn(at + ": chunk with a bad CRC skipped");
      return std::nullopt;
    }
    return records;
  }

  void parse_schema(std::string_view body, const std::string& at) {
    ByteReader r(body, at);
    const uint16_t id = r.u16();
    schemas_[id] = std::string(r.str32());
  }

  void parse_channel(std::string_view body, const std::string& at) {
    ByteReader r(body, at);
    ChannelInfo c;
    c.id = r.u16();
    const uint16_t schema = r.u16();
    c.topic = std::string(r.str32());
    c.encoding = encoding_from_name(r.str32());
    auto it = schemas_.find(schema);
    if (schema != 0 && it == schemas_.end()) r.fail("channel " + c.topic + " refers to unknown schema " + std::to_string(schema));
    if (it != schemas_.end()) c.type = it->second;
    channels_.try_emplace(uint16_t(c.id), std::move(c));
  }

  bool read_summary();
  void parse_summary_record(uint8_t op, std::string_view body, const std::string& at, bool& have_stats);
  void scan_linear();
  void scan_chunk(uint64_t offset, std::map<uint16_t, uint64_t>& counts, bool& any);

  std::unique_ptr<ByteSource> src_;
  std::map<uint16_t, std::string> schemas_;  // id -> name
  std::map<uint16_t, ChannelInfo> channels_;
  std::vector<ChannelInfo> infos_;
  std::vector<ChunkRef> chunks_;
  uint64_t stats_chunks_ = 0;
  bool no_footer_ = false;
};

void McapReader::parse_summary_record(uint8_t op, std::string_view body, const std::string& at, bool& have_stats) {
  if (op == kSchema) parse_schema(body, at);
  if (op == kChannel) parse_channel(body, at);
  ByteReader r(body, at);
  if (op == kChunkIndex) {
    ChunkRef c;
    c.start_ns = int64_t(r.u64());
    c.end_ns = int64_t(r.u64());
    c.offset = r.u64();
    r.u64();
    ByteReader map(r.bytes(r.u32()), at);
    while (!map.done()) {
      c.channels.push_back(map.u16());
      map.u64();
    }
    chunks_.push_back(std::move(c));
  } else if (op == kStatistics) {
    have_stats = true;
    r.u64();
    r.skip(2 + 4 + 4 + 4);
    stats_chunks_ = r.u32();
    start_ns_ = int64_t(r.u64());
    end_ns_ = int64_t(r.u64());
    ByteReader map(r.bytes(r.u32()), at);
    while (!map.done()) {
      const uint16_t id = map.u16();
      const uint64_t n = map.u64();
      auto it = channels_.find(id);
      if (it != channels_.end()) it->second.count = n;
    }
  }
}

// False when there is no usable summary (no footer, no statistics, unchunked messages).
bool McapReader::read_summary() {
  const uint64_t size = src_->size();
  if (size < kMagic.size() * 2 + kFooterRecord) return false;
  const uint64_t footer_at = size - kMagic.size() - kFooterRecord;
  std::string tail;
  src_->read(footer_at, kFooterRecord + kMagic.size(), tail);
  ByteReader r(tail, where(footer_at));
  if (tail.substr(kFooterRecord) != kMagic || r.u8() != kFooter || r.u64() != 20) {
    no_footer_ = true;  // scan_linear() warns, once: where the file is cut, or that the footer is missing
    return false;
  }
  const uint64_t start = r.u64(), offsets = r.u64();
  const uint64_t end = offsets ? offsets : footer_at;
  if (start == 0) return false;
  if (start < kMagic.size() || start > end || end > footer_at) r.fail("summary section offsets out of range");
  std::string summary;
  src_->read(start, end - start, summary);
  bool have_stats = false;
  for_each_record(summary, path_ + ": summary section", [&](uint8_t op, std::string_view body, size_t at) {
    parse_summary_record(op, body, where(start + at), have_stats);
  });
  if (!have_stats || stats_chunks_ != chunks_.size() || (chunks_.empty() && end_ns_ != 0)) {
    chunks_.clear();
    channels_.clear();
    schemas_.clear();
    start_ns_ = end_ns_ = 0;
    return false;
  }
  return true;
}

void McapReader::scan_chunk(uint64_t offset, std::map<uint16_t, uint64_t>& counts, bool& any) {
  std::string buf;
  const std::optional<std::string_view> records = load_chunk(offset, buf);
  if (!records) return;
  ChunkRef c;
  c.offset = offset;
  c.start_ns = std::numeric_limits<int64_t>::max();
  c.end_ns = std::numeric_limits<int64_t>::min();
  for_each_record(*records, where(offset), [&](uint8_t op, std::string_view body, size_t) {
    if (op == kSchema) parse_schema(body, where(offset));
    if (op == kChannel) parse_channel(body, where(offset));
    if (op != kMessage) return;
    ByteReader r(body, where(offset));
    const uint16_t ch = r.u16();
    r.u32();
    const int64_t t = int64_t(r.u64());
    ++counts[ch];
    c.start_ns = std::min(c.start_ns, t);
    c.end_ns = std::max(c.end_ns, t);
    if (std::find(c.channels.begin(), c.channels.end(), ch) == c.channels.end()) c.channels.push_back(ch);
  });
  if (c.channels.empty()) return;
  start_ns_ = any ? std::min(start_ns_, c.start_ns) : c.start_ns;
  end_ns_ = any ? std::max(end_ns_, c.end_ns) : c.end_ns;
  any = true;
  chunks_.push_back(std::move(c));
}

void McapReader::scan_linear() {
  std::map<uint16_t, uint64_t> counts;
  bool any = false;
  const uint64_t size = src_->size();
  uint64_t pos = kMagic.size();
  std::string rec;
  bool cut = false;  // warned where
  while (true) {
    if (size - pos < 9) {
      cut = size != pos;
      if (cut) warn(path_ + ": truncated after offset " + std::to_string(pos));
      break;
    }
    src_->read(pos, 9, rec);
    ByteReader h(rec, where(pos));
    const uint8_t op = h.u8();
    const uint64_t len = h.u64();
    if (len > size - pos - 9) {
      warn(path_ + ": truncated in the record at offset " + std::to_string(pos) + ": read what precedes it");
      cut = true;
      break;
    }
    if (op == kDataEnd || op == kFooter) break;
    if (op == kChunk) scan_chunk(pos, counts, any);
    if (op == kSchema || op == kChannel || op == kMessage) {
      src_->read(pos + 9, len, rec);
      if (op == kSchema) parse_schema(rec, where(pos));
      if (op == kChannel) parse_channel(rec, where(pos));
      if (op == kMessage) {
        ByteReader r(rec, where(pos));
        const uint16_t ch = r.u16();
        r.u32();
        const int64_t t = int64_t(r.u64());
        ++counts[ch];
        chunks_.push_back({pos, t, t, {ch}, true});
        start_ns_ = any ? std::min(start_ns_, t) : t;
        end_ns_ = any ? std::max(end_ns_, t) : t;
        any = true;
      }
    }
    pos += 9 + len;
  }
  for (auto& [id, c] : channels_) c.count = counts.count(id) ? counts[id] : 0;
  if (no_footer_ && !cut) warn(path_ + ": no MCAP footer (truncated or still being written): read up to the end");
}

}  // namespace

std::unique_ptr<BagReader> open_mcap(std::unique_ptr<ByteSource> src) { return std::make_unique<McapReader>(std::move(src)); }

}  // namespace gcmap::detail
