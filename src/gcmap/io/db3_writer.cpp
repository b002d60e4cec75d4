// rosbag2 sqlite3 writer: a folder NAME/ with NAME_0.db3 (NAME_1.db3, ... when split) and
// metadata.yaml, built under a temporary name and renamed into place by close().
#include <sqlite3.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <map>

#include "gcmap/core/error.hpp"
#include "gcmap/io/bag_writer.hpp"

namespace gcmap::detail {

namespace {

namespace fs = std::filesystem;

constexpr const char* kSchema =
    "CREATE TABLE schema(schema_version INTEGER PRIMARY KEY, ros_distro TEXT NOT NULL);"
    "INSERT INTO schema VALUES(3, 'humble');"
    "CREATE TABLE topics(id INTEGER PRIMARY KEY, name TEXT NOT NULL, type TEXT NOT NULL, "
    "serialization_format TEXT NOT NULL, offered_qos_profiles TEXT NOT NULL);"
    "CREATE TABLE messages(id INTEGER PRIMARY KEY, topic_id INTEGER NOT NULL, timestamp INTEGER NOT NULL, "
    "data BLOB NOT NULL);"
    "CREATE INDEX timestamp_idx ON messages (timestamp ASC);";

std::string without_slash(std::string p) {
  while (p.size() > 1 && p.back() == '/') p.pop_back();
  return p;
}

struct Topic {
  std::string name, type;
  uint64_t count = 0;
};

class Db3Writer : public BagWriter {
 public:
  Db3Writer(const std::string& path, const BagWriterOptions& o)
      : path_(without_slash(path)), tmp_(path_ + ".tmp." + std::to_string(::getpid())), o_(o) {
    if (o.compression != Compression::none) throw Error(path + ": db3 bags are written uncompressed");
    std::error_code ec;
    fs::remove_all(tmp_, ec);
    if (!fs::create_directories(tmp_, ec)) throw Error(path + ": cannot create folder " + tmp_);
    name_ = fs::path(path_).filename().string();
  }
  ~Db3Writer() override {
    close_db();
    if (!committed_) {
      std::error_code ec;
      fs::remove_all(tmp_, ec);
    }
  }

  uint32_t add_topic(const std::string& topic, const std::string& type) override {
    topics_.push_back({topic, type, 0});
    if (db_) insert_topic(topics_.size() - 1);
    return uint32_t(topics_.size() - 1);
  }

  void write(uint32_t topic, int64_t time_ns, std::string_view data) override {
    if (!db_ || (o_.db3_messages_per_file && in_file_ >= o_.db3_messages_per_file)) next_file();
    sqlite3_bind_int64(insert_, 1, int64_t(topic) + 1);
    sqlite3_bind_int64(insert_, 2, time_ns);
    sqlite3_bind_blob64(insert_, 3, data.data(), data.size(), SQLITE_STATIC);
    if (sqlite3_step(insert_) != SQLITE_DONE) fail("insert failed");
    sqlite3_reset(insert_);
    ++topics_.at(topic).count;
    start_ = count_ ? std::min(start_, time_ns) : time_ns;
    end_ = count_ ? std::max(end_, time_ns) : time_ns;
    ++count_;
    ++in_file_;
  }

  void close() override {
    if (!db_) next_file();
    close_db();
    write_metadata();
    std::error_code ec;
    if (fs::exists(path_, ec)) {
      if (!fs::exists(fs::path(path_) / "metadata.yaml", ec)) throw Error(path_ + ": exists and is not a bag folder");
      fs::remove_all(path_, ec);
    }
    fs::rename(tmp_, path_, ec);
    if (ec) throw Error(path_ + ": cannot rename temporary folder (" + ec.message() + ")");
    committed_ = true;
  }

 private:
  [[noreturn]] void fail(const std::string& what) { throw Error(path_ + ": " + what + " (" + sqlite3_errmsg(db_) + ")"); }

  void exec(const char* sql) {
    if (sqlite3_exec(db_, sql, nullptr, nullptr, nullptr) != SQLITE_OK) fail(std::string("sqlite: ") + sql);
  }

  void insert_topic(size_t i) {
    sqlite3_stmt* s = nullptr;
    sqlite3_prepare_v2(db_, "INSERT INTO topics VALUES(?, ?, ?, 'cdr', '')", -1, &s, nullptr);
    sqlite3_bind_int64(s, 1, int64_t(i) + 1);
    sqlite3_bind_text(s, 2, topics_[i].name.c_str(), -1, SQLITE_TRANSIENT);
    sqlite3_bind_text(s, 3, topics_[i].type.c_str(), -1, SQLITE_TRANSIENT);
    const int rc = sqlite3_step(s);
    sqlite3_finalize(s);
    if (rc != SQLITE_DONE) fail("cannot add topic " + topics_[i].name);
  }

  void next_file() {
    close_db();
    files_.push_back(name_ + "_" + std::to_string(files_.size()) + ".db3");
    if (sqlite3_open((fs::path(tmp_) / files_.back()).c_str(), &db_) != SQLITE_OK) fail("cannot create " + files_.back());
    exec(kSchema);
    for (size_t i = 0; i < topics_.size(); ++i) insert_topic(i);
    exec("BEGIN");
    if (sqlite3_prepare_v2(db_, "INSERT INTO messages(topic_id, timestamp, data) VALUES(?, ?, ?)", -1, &insert_, nullptr) !=
        SQLITE_OK)
      fail("prepare");
    in_file_ = 0;
  }

  void close_db() {
    if (!db_) return;
    sqlite3_finalize(insert_);
    insert_ = nullptr;
    sqlite3_exec(db_, "COMMIT", nullptr, nullptr, nullptr);
    sqlite3_close(db_);
    db_ = nullptr;
  }

  void write_metadata() const {
    std::ofstream out(fs::path(tmp_) / "metadata.yaml");
    out << "rosbag2_bagfile_information:\n  version: 5\n  storage_identifier: sqlite3\n"
        << "  duration:\n    nanoseconds: " << (end_ - start_) << "\n"
        << "  starting_time:\n    nanoseconds_since_epoch: " << start_ << "\n"
        << "  message_count: " << count_ << "\n  topics_with_message_count:\n";
    for (const Topic& t : topics_)
      out << "    - topic_metadata:\n        name: " << t.name << "\n        type: " << t.type
          << "\n        serialization_format: cdr\n        offered_qos_profiles: \"\"\n      message_count: " << t.count << "\n";
    out << "  compression_format: \"\"\n  compression_mode: \"\"\n  relative_file_paths:\n";
    for (const std::string& f : files_) out << "    - " << f << "\n";
    if (!out) throw Error(path_ + ": cannot write metadata.yaml");
  }

  std::string path_, tmp_, name_;
  BagWriterOptions o_;
  std::vector<Topic> topics_;
  std::vector<std::string> files_;
  sqlite3* db_ = nullptr;
  sqlite3_stmt* insert_ = nullptr;
  int64_t start_ = 0, end_ = 0;
  uint64_t count_ = 0, in_file_ = 0;
  bool committed_ = false;
};

}  // namespace

std::unique_ptr<BagWriter> make_db3_writer(const std::string& path, const BagWriterOptions& o) {
  return std::make_unique<Db3Writer>(path, o);
}

}  // namespace gcmap::detail
