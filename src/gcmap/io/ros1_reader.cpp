// ROS 1 bag v2.0 (http://wiki.ros.org/Bags/Format/2.0): "#ROSBAG V2.0\n", then records
// <header_len u32><header: fields <len u32>name=value><data_len u32><data>; messages live in
// (optionally bz2/lz4-compressed) chunk records; connections and chunk infos form the index at the end.

#include <algorithm>
#include <map>

#include "gcmap/core/error.hpp"
#include "gcmap/io/bag_bytes.hpp"
#include "gcmap/io/bag_chunks.hpp"
#include "gcmap/io/compression.hpp"

namespace gcmap::detail {

namespace {

constexpr std::string_view kMagic = "#ROSBAG V2.0\n";
enum Op : uint8_t { kMessage = 2, kBagHeader = 3, kChunk = 5, kChunkInfo = 6, kConnection = 7 };

struct Record {
  std::vector<std::pair<std::string_view, std::string_view>> fields;
  std::string_view data;
  std::string where;

  std::string_view field(std::string_view name) const {
    for (auto& [k, v] : fields)
      if (k == name) return v;
    throw Error(where + ": record lacks the field '" + std::string(name) + "'");
  }
  template <typename T>
  T num(std::string_view name) const {
    std::string_view v = field(name);
    if (v.size() != sizeof(T)) throw Error(where + ": field '" + std::string(name) + "' has the wrong size");
    T x;
    std::memcpy(&x, v.data(), sizeof(T));
    return x;
  }
  int64_t time(std::string_view name) const {
    const uint64_t v = num<uint64_t>(name);
    return int64_t(v & 0xFFFFFFFFu) * 1000000000 + int64_t(v >> 32);
  }
  uint8_t op() const { return num<uint8_t>("op"); }
};

// Fields of a ROS 1 header block (record headers and connection data share the format).
void parse_fields(std::string_view block, const std::string& where, Record& rec) {
  ByteReader h(block, where);
  while (!h.done()) {
    std::string_view f = h.str32();
    const size_t eq = f.find('=');
    if (eq == std::string_view::npos) h.fail("header field without '='");
    rec.fields.emplace_back(f.substr(0, eq), f.substr(eq + 1));
  }
}

Record parse_record(ByteReader& r, const std::string& where) {
  Record rec;
  rec.where = where;
  parse_fields(r.str32(), where, rec);
  rec.data = r.str32();
  return rec;
}

class Ros1Reader : public BagReader {
 public:
  explicit Ros1Reader(std::unique_ptr<ByteSource> src) : src_(std::move(src)) {
    path_ = src_->name();
    format_ = BagFormat::ros1;
    std::string head;
    src_->read(0, std::min<uint64_t>(src_->size(), kMagic.size()), head);
    if (head != kMagic)
      throw Error(path_ + (head.rfind("#ROSBAG V", 0) == 0 ? ": unsupported ROS bag version (2.0 only)" : ": not a ROS 1 bag"));
    std::string buf;
    const uint64_t first = kMagic.size() + read_record(kMagic.size(), buf);
    ByteReader r(buf, where(kMagic.size()));
    const Record header = parse_record(r, where(kMagic.size()));
    if (header.op() != kBagHeader) r.fail("expected the bag header record");
    const uint64_t index_pos = header.num<uint64_t>("index_pos");
    const uint32_t chunk_count = header.num<uint32_t>("chunk_count");
    bool indexed = index_pos >= first && index_pos <= src_->size();
    if (indexed) {
      try {
        read_index(index_pos);
        indexed = chunks_.size() == chunk_count;
      } catch (const Error& e) { indexed = false; }
    }
    if (!indexed && !scan_linear(first))  // one warning: where the file is cut, else that the index is missing
      warn(path_ + ": no valid index (bag not closed): read every chunk");
    for (auto& [id, c] : connections_) infos_.push_back(c);
    topics_ = group_topics(infos_);
  }

  std::unique_ptr<MessageCursor> read(const std::string& name, int64_t begin_ns, int64_t end_ns) override {
    topic(name);
    std::vector<uint32_t> ids = channels_of(infos_, name);
    auto load = [this, ids, begin_ns, end_ns](const ChunkRef& c, std::vector<PendingMessage>& out) {
      auto buf = std::make_shared<std::string>();
      load_chunk(c.offset, *buf);
      for_each_inner(*buf, c.offset, [&](const Record& rec) {
        if (rec.op() != kMessage) return;
        const int64_t t = rec.time("time");
        const uint32_t conn = rec.num<uint32_t>("conn");
        if (t < begin_ns || t > end_ns || std::find(ids.begin(), ids.end(), conn) == ids.end()) return;
        out.push_back({t, rec.data, buf});
      });
    };
    return merge_chunks(chunks_, ids, begin_ns, end_ns, load);
  }

 private:
  // Reads the whole record at `pos` into `out`; returns its length.
  uint64_t read_record(uint64_t pos, std::string& out) const {
    std::string len;
    src_->read(pos, 4, len);
    const uint64_t hl = ByteReader(len, where(pos)).u32();
    src_->read(pos + 4 + hl, 4, len);
    const uint64_t dl = ByteReader(len, where(pos)).u32();
    src_->read(pos, 8 + hl + dl, out);
    return 8 + hl + dl;
  }

  template <typename F>
  void for_each_inner(std::string_view records, uint64_t chunk_at, F&& f) const {
    ByteReader r(records, where(chunk_at) + " (inside the chunk)");
    while (!r.done()) f(parse_record(r, where(chunk_at) + " (inside the chunk)"));
  }

  void load_chunk(uint64_t offset, std::string& out) const {
    std::string buf;
    read_record(offset, buf);
    ByteReader r(buf, where(offset));
    const Record rec = parse_record(r, where(offset));
    if (rec.op() != kChunk) r.fail("expected a chunk record");
    const std::string_view comp = rec.field("compression");
    Compression c = Compression::none;
    if (comp == "bz2") c = Compression::bz2;
    else if (comp == "lz4") c = Compression::lz4;
    else if (comp != "none") r.fail("unknown compression '" + std::string(comp) + "'");
    decompress(c, rec.data, rec.num<uint32_t>("size"), true, out, where(offset));
  }

  void add_connection(const Record& rec) {
    ChannelInfo c;
    c.id = rec.num<uint32_t>("conn");
    c.topic = std::string(rec.field("topic"));
    Record meta;
    meta.where = rec.where;
    parse_fields(rec.data, rec.where, meta);
    c.type = std::string(meta.field("type"));
    c.encoding = MessageEncoding::ros1;
    connections_.try_emplace(c.id, std::move(c));
  }

  void read_index(uint64_t pos);
  // Indexes every chunk from `pos`; true, with a warning, when the file is cut.
  bool scan_linear(uint64_t pos);
  void scan_chunk(uint64_t offset, bool& any);

  std::unique_ptr<ByteSource> src_;
  std::map<uint32_t, ChannelInfo> connections_;
  std::vector<ChannelInfo> infos_;
  std::vector<ChunkRef> chunks_;
};

void Ros1Reader::read_index(uint64_t pos) {
  std::string buf;
  bool any = false;
  while (pos < src_->size()) {
    const uint64_t len = read_record(pos, buf);
    ByteReader r(buf, where(pos));
    const Record rec = parse_record(r, where(pos));
    if (rec.op() == kConnection) add_connection(rec);
    if (rec.op() == kChunkInfo) {
      ChunkRef c;
      c.offset = rec.num<uint64_t>("chunk_pos");
      c.start_ns = rec.time("start_time");
      c.end_ns = rec.time("end_time");
      ByteReader d(rec.data, rec.where);
      while (!d.done()) {
        c.channels.push_back(d.u32());
        const uint32_t n = d.u32();
        auto it = connections_.find(c.channels.back());
        if (it != connections_.end()) it->second.count += n;
      }
      start_ns_ = any ? std::min(start_ns_, c.start_ns) : c.start_ns;
      end_ns_ = any ? std::max(end_ns_, c.end_ns) : c.end_ns;
      any = true;
      chunks_.push_back(std::move(c));
    }
    pos += len;
  }
}

void Ros1Reader::scan_chunk(uint64_t offset, bool& any) {
  std::string buf;
  load_chunk(offset, buf);
  ChunkRef c;
  c.offset = offset;
  c.start_ns = std::numeric_limits<int64_t>::max();
  c.end_ns = std::numeric_limits<int64_t>::min();
  for_each_inner(buf, offset, [&](const Record& rec) {
    if (rec.op() == kConnection) add_connection(rec);
    if (rec.op() != kMessage) return;
    const uint32_t conn = rec.num<uint32_t>("conn");
    const int64_t t = rec.time("time");
    auto it = connections_.find(conn);
    if (it == connections_.end()) throw Error(rec.where + ": message on an undeclared connection " + std::to_string(conn));
    ++it->second.count;
    c.start_ns = std::min(c.start_ns, t);
    c.end_ns = std::max(c.end_ns, t);
    if (std::find(c.channels.begin(), c.channels.end(), conn) == c.channels.end()) c.channels.push_back(conn);
  });
  if (c.channels.empty()) return;
  start_ns_ = any ? std::min(start_ns_, c.start_ns) : c.start_ns;
  end_ns_ = any ? std::max(end_ns_, c.end_ns) : c.end_ns;
  any = true;
  chunks_.push_back(std::move(c));
}

bool Ros1Reader::scan_linear(uint64_t pos) {
  chunks_.clear();
  connections_.clear();
  start_ns_ = end_ns_ = 0;
  bool any = false;
  std::string buf;
  while (pos < src_->size()) {
    uint64_t len = 0;
    try {
      len = read_record(pos, buf);
    } catch (const Error&) {
      warn(path_ + ": truncated in the record at offset " + std::to_string(pos) + " (no valid index): read what precedes it");
      return true;
    }
    ByteReader r(buf, where(pos));
    const Record rec = parse_record(r, where(pos));
    if (rec.op() == kChunk) scan_chunk(pos, any);
    if (rec.op() == kConnection) add_connection(rec);
    pos += len;
  }
  return false;
}

}  // namespace

std::unique_ptr<BagReader> open_ros1(std::unique_ptr<ByteSource> src) { return std::make_unique<Ros1Reader>(std::move(src)); }

}  // namespace gcmap::detail
