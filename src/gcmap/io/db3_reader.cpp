// rosbag2 sqlite3 storage: a folder with metadata.yaml and one or more .db3 files, each with tables
// topics(id, name, type, serialization_format, ...) and messages(id, topic_id, timestamp, data).
#include <spdlog/spdlog.h>
#include <sqlite3.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <filesystem>
#include <fstream>

#include "gcmap/core/error.hpp"
#include "gcmap/io/bag_chunks.hpp"
#include "gcmap/io/compression.hpp"

namespace gcmap::detail {

namespace {

namespace fs = std::filesystem;
constexpr uint64_t kMaxMessageBytes = uint64_t(1) << 32;

using Statement = std::unique_ptr<sqlite3_stmt, int (*)(sqlite3_stmt*)>;

struct DbFile {
  std::string name;
  std::string bytes;  // the database image when read from memory (sqlite reads it in place)
  sqlite3* db = nullptr;
  std::vector<std::pair<std::string, int64_t>> topic_ids;  // name -> topics.id in this file

  DbFile() = default;
  DbFile(const DbFile&) = delete;
  ~DbFile() { sqlite3_close(db); }

  [[noreturn]] void fail(const std::string& what) const {
    throw Error(name + ": " + what + (db ? std::string(" (") + sqlite3_errmsg(db) + ")" : ""));
  }
  Statement prepare(const char* sql) const {
    sqlite3_stmt* s = nullptr;
    if (sqlite3_prepare_v2(db, sql, -1, &s, nullptr) != SQLITE_OK) fail("not a rosbag2 sqlite3 database");
    return Statement(s, sqlite3_finalize);
  }
  int step(sqlite3_stmt* s) const {
    const int rc = sqlite3_step(s);
    if (rc != SQLITE_ROW && rc != SQLITE_DONE) fail("corrupt database");
    return rc;
  }
};

std::string column_text(sqlite3_stmt* s, int i) {
  const auto* t = sqlite3_column_text(s, i);
  return t ? std::string(reinterpret_cast<const char*>(t)) : std::string();
}

class Db3Cursor : public MessageCursor {
 public:
  Db3Cursor(std::vector<std::pair<const DbFile*, Statement>> streams, bool zstd, const std::string& where)
      : zstd_(zstd), where_(where) {
    for (auto& [file, stmt] : streams) streams_.push_back({file, std::move(stmt), false});
    for (Stream& s : streams_) advance(s);
  }

  bool next(BagMessage& msg) override {
    if (last_) advance(*last_);
    last_ = nullptr;
    for (Stream& s : streams_)
      if (s.has_row && (!last_ || sqlite3_column_int64(s.stmt.get(), 0) < sqlite3_column_int64(last_->stmt.get(), 0))) last_ = &s;
    if (!last_) return false;
    sqlite3_stmt* st = last_->stmt.get();
    msg.time_ns = sqlite3_column_int64(st, 0);
    const char* blob = static_cast<const char*>(sqlite3_column_blob(st, 1));
    msg.data = std::string_view(blob ? blob : "", size_t(sqlite3_column_bytes(st, 1)));
    if (zstd_) {
      decompress(Compression::zstd, msg.data, kMaxMessageBytes, false, buffer_, where_);
      msg.data = buffer_;
    }
    return true;
  }

 private:
  struct Stream {
    const DbFile* file;
    Statement stmt;
    bool has_row;
  };
  void advance(Stream& s) { s.has_row = s.file->step(s.stmt.get()) == SQLITE_ROW; }

  std::vector<Stream> streams_;
  Stream* last_ = nullptr;
  bool zstd_;
  std::string where_, buffer_;
};

class Db3Reader : public BagReader {
 public:
  // `files` are opened in order; with `bytes` a single in-memory database.
  Db3Reader(const std::string& path, std::vector<std::string> files, std::string bytes) {
    path_ = path;
    format_ = BagFormat::db3;
    for (std::string& f : files) {
      auto db = std::make_unique<DbFile>();
      db->name = f;
      db->bytes = std::move(bytes);
      open(*db);
      files_.push_back(std::move(db));
    }
    for (auto& f : files_) load_topics(*f);
    topics_ = group_topics(infos_);
  }

  void set_message_compression(bool zstd) { zstd_ = zstd; }

  std::unique_ptr<MessageCursor> read(const std::string& name, int64_t begin_ns, int64_t end_ns) override {
    topic(name);
    std::vector<std::pair<const DbFile*, Statement>> streams;
    for (auto& f : files_)
      for (auto& [topic, id] : f->topic_ids) {
        if (topic != name) continue;
        Statement s = f->prepare(
            "SELECT timestamp, data FROM messages WHERE topic_id = ? AND timestamp >= ? AND timestamp <= ? "
            "ORDER BY timestamp, id");
        sqlite3_bind_int64(s.get(), 1, id);
        sqlite3_bind_int64(s.get(), 2, begin_ns);
        sqlite3_bind_int64(s.get(), 3, end_ns);
        streams.emplace_back(f.get(), std::move(s));
      }
    return std::make_unique<Db3Cursor>(std::move(streams), zstd_, path_ + ": topic " + name);
  }

 private:
  static void open(DbFile& f) {
    if (f.bytes.empty()) {
      if (sqlite3_open_v2(f.name.c_str(), &f.db, SQLITE_OPEN_READONLY, nullptr) != SQLITE_OK) f.fail("cannot open");
      return;
    }
    if (sqlite3_open(":memory:", &f.db) != SQLITE_OK) f.fail("cannot open");
    auto* data = reinterpret_cast<unsigned char*>(f.bytes.data());
    if (sqlite3_deserialize(f.db, "main", data, sqlite3_int64(f.bytes.size()), sqlite3_int64(f.bytes.size()),
                            SQLITE_DESERIALIZE_READONLY) != SQLITE_OK)
      f.fail("not an sqlite3 database");
  }

  // A cut file: sqlite reads its missing end as zeros or calls it malformed. The header's page size
  // (offset 16) and page count (offset 28, valid when the change counters at 24 and 92 agree) tell.
  static void check_size(DbFile& f) {
    std::string head = f.bytes.substr(0, 100);
    uint64_t actual = f.bytes.size();
    if (f.bytes.empty()) {
      std::error_code ec;
      if (fs::exists(f.name + "-wal", ec)) return;  // pages may live in the write-ahead log
      actual = fs::file_size(f.name, ec);
      std::ifstream in(f.name, std::ios::binary);
      head.resize(100);
      head.resize(in.read(head.data(), 100) ? 100 : 0);
    }
    if (head.size() < 100) return;  // sqlite tells what is wrong with it
    auto be = [&](size_t at, int n) {
      uint64_t v = 0;
      for (int k = 0; k < n; ++k) v = v << 8 | uint8_t(head[at + k]);
      return v;
    };
    const uint64_t page = be(16, 2) == 1 ? 65536 : be(16, 2), declared = be(28, 4) * page;
    if (be(24, 4) == be(92, 4) && declared > actual)
      throw Error(f.name + ": truncated database (" + std::to_string(actual) + " of " + std::to_string(declared) + " bytes)");
  }

  void load_topics(DbFile& f) {
    check_size(f);
    Statement t = f.prepare("SELECT id, name, type, serialization_format FROM topics");
    std::vector<ChannelInfo> here;
    while (f.step(t.get()) == SQLITE_ROW) {
      ChannelInfo c;
      c.id = uint32_t(infos_.size() + here.size());
      f.topic_ids.emplace_back(column_text(t.get(), 1), sqlite3_column_int64(t.get(), 0));
      c.topic = f.topic_ids.back().first;
      c.type = column_text(t.get(), 2);
      c.encoding = encoding_from_name(column_text(t.get(), 3));
      here.push_back(std::move(c));
    }
    Statement n = f.prepare("SELECT topic_id, COUNT(*), MIN(timestamp), MAX(timestamp) FROM messages GROUP BY topic_id");
    while (f.step(n.get()) == SQLITE_ROW) {
      const int64_t id = sqlite3_column_int64(n.get(), 0);
      const int64_t t0 = sqlite3_column_int64(n.get(), 2), t1 = sqlite3_column_int64(n.get(), 3);
      for (size_t i = 0; i < f.topic_ids.size(); ++i)
        if (f.topic_ids[i].second == id) here[i].count = uint64_t(sqlite3_column_int64(n.get(), 1));
      start_ns_ = any_ ? std::min(start_ns_, t0) : t0;
      end_ns_ = any_ ? std::max(end_ns_, t1) : t1;
      any_ = true;
    }
    infos_.insert(infos_.end(), here.begin(), here.end());
  }

  std::vector<std::unique_ptr<DbFile>> files_;
  std::vector<ChannelInfo> infos_;
  bool any_ = false;
  bool zstd_ = false;
};

// The .db3 files of a bag folder, from metadata.yaml (or every .db3 file when there is none), and
// whether messages are zstd-compressed one by one.
std::vector<std::string> bag_files(const fs::path& dir, bool& zstd_messages) {
  std::vector<std::string> files;
  const fs::path meta = dir / "metadata.yaml";
  std::error_code ec;
  if (!fs::exists(meta, ec)) {
    for (const auto& e : fs::directory_iterator(dir, ec))
      if (e.path().extension() == ".db3") files.push_back(e.path().string());
    std::sort(files.begin(), files.end());
    if (files.empty()) throw Error(dir.string() + ": no metadata.yaml and no .db3 file: not a ROS 2 bag");
    return files;
  }
  try {
    const YAML::Node info = YAML::LoadFile(meta.string())["rosbag2_bagfile_information"];
    if (!info) throw Error(meta.string() + ": no rosbag2_bagfile_information");
    const std::string storage = info["storage_identifier"] ? info["storage_identifier"].as<std::string>() : "sqlite3";
    if (storage != "sqlite3")
      throw Error(meta.string() + ": storage " + storage + " is not sqlite3 (open the .mcap file itself)");
    const std::string format = info["compression_format"] ? info["compression_format"].as<std::string>() : "";
    const std::string mode = info["compression_mode"] ? info["compression_mode"].as<std::string>() : "";
    if (!format.empty() && format != "zstd") throw Error(meta.string() + ": unknown compression_format " + format);
    if (mode == "FILE" && !format.empty())
      throw Error(meta.string() + ": compression_mode FILE is not supported (run `ros2 bag decompress` first)");
    zstd_messages = mode == "MESSAGE" && format == "zstd";
    for (const auto& f : info["relative_file_paths"]) files.push_back((dir / f.as<std::string>()).string());
  } catch (const YAML::Exception& e) { throw Error(meta.string() + ": " + e.what()); }
  if (files.empty()) throw Error(meta.string() + ": relative_file_paths lists no file");
  return files;
}

}  // namespace

std::unique_ptr<BagReader> open_db3(const std::string& path) {
  std::error_code ec;
  if (!fs::is_directory(path, ec)) return std::make_unique<Db3Reader>(path, std::vector<std::string>{path}, "");
  bool zstd = false;
  std::vector<std::string> files = bag_files(path, zstd);
  auto reader = std::make_unique<Db3Reader>(path, std::move(files), "");
  reader->set_message_compression(zstd);
  return reader;
}

std::unique_ptr<BagReader> open_db3_bytes(std::string bytes, const std::string& name) {
  if (bytes.empty()) throw Error(name + ": empty file");
  return std::make_unique<Db3Reader>(name, std::vector<std::string>{name}, std::move(bytes));
}

}  // namespace gcmap::detail
