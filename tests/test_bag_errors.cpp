// Damaged bags: every cut point and random corruption gives a gcmap::Error or messages that were
// really written (a truncated file reads as far as it is intact); bad CRCs and unknown compression.
#include <gtest/gtest.h>

#include <filesystem>
#include <map>
#include <random>

#include <sqlite3.h>

#include "bag_test_util.hpp"
#include "gcmap/core/error.hpp"
#include "test_util.hpp"

namespace gcmap::test {
namespace {

using Messages = std::vector<std::pair<int64_t, std::string>>;

// Writes 6 scans on /points and 6 strings on /chatter; returns the file's bytes (db3: the .db3).
std::string write_sample(const Container& c, const TempDir& dir, std::map<std::string, Messages>& written) {
  const std::string path = dir / bag_name(c);
  BagWriterOptions o = c.options;
  o.db3_messages_per_file = 0;
  o.chunk_bytes = 1500;
  auto w = open_bag_writer(path, c.format, o);
  const uint32_t pts = w->add_topic("/points", "sensor_msgs/msg/PointCloud2");
  const uint32_t chat = w->add_topic("/chatter", "std_msgs/msg/String");
  for (int k = 0; k < 6; ++k) {
    const std::string scan = encode_scan(make_scan(40, k), 100.0 + k, CloudLayout{}, message_encoding(c.format));
    const std::string text = "hello " + std::to_string(k);
    w->write(pts, (100 + k) * 1'000'000'000LL, scan);
    w->write(chat, (100 + k) * 1'000'000'000LL + 5, text);
    written["/points"].emplace_back((100 + k) * 1'000'000'000LL, scan);
    written["/chatter"].emplace_back((100 + k) * 1'000'000'000LL + 5, text);
  }
  w->close();
  if (c.format != BagFormat::db3) return read_file(path);
  return read_file((std::filesystem::path(path) / (c.name + "_0.db3")).string());
}

// All messages of every topic, decoding the point clouds too.
std::map<std::string, Messages> read_all(BagFormat f, std::string bytes) {
  std::map<std::string, Messages> out;
  auto bag = open_bag_bytes(f, std::move(bytes), "damaged");
  for (const BagTopic& t : bag->topics()) {
    auto cur = bag->read(t.name);
    for (BagMessage m; cur->next(m);) {
      out[t.name].emplace_back(m.time_ns, std::string(m.data));
      if (t.name == "/points") decode_scan(t, m.data, "damaged");
    }
  }
  return out;
}

bool contains(const Messages& all, const std::pair<int64_t, std::string>& m) {
  return std::find(all.begin(), all.end(), m) != all.end();
}

TEST(BagErrors, TruncatedFilesReadAsFarAsIntact) {
  TempDir dir;
  for (const Container& c : containers()) {
    if (c.name == "db3-split") continue;
    SCOPED_TRACE(c.name);
    std::map<std::string, Messages> written;
    const std::string bytes = write_sample(c, dir, written);
    EXPECT_EQ(read_all(c.format, bytes), written);
    int partial = 0;
    for (size_t cut = 0; cut < bytes.size(); cut += std::max<size_t>(1, bytes.size() / 150)) {
      SCOPED_TRACE("cut at " + std::to_string(cut) + " of " + std::to_string(bytes.size()));
      try {
        const auto got = read_all(c.format, bytes.substr(0, cut));
        size_t n = 0;
        for (auto& [topic, msgs] : got) {
          for (auto& m : msgs) ASSERT_TRUE(contains(written[topic], m)) << topic << " at " << m.first;
          n += msgs.size();
        }
        partial += n > 0;
      } catch (const Error&) {}
    }
    // MCAP and ROS 1 recover the complete chunks of a cut file; sqlite refuses a cut database.
    if (c.format != BagFormat::db3) EXPECT_GT(partial, 20);
  }
}

TEST(BagErrors, RandomCorruptionNeverCrashes) {
  TempDir dir;
  std::mt19937 rng(7);
  for (const Container& c : containers()) {
    if (c.name == "db3-split") continue;
    SCOPED_TRACE(c.name);
    std::map<std::string, Messages> written;
    const std::string bytes = write_sample(c, dir, written);
    for (int trial = 0; trial < 150; ++trial) {
      std::string bad = bytes;
      for (int k = 0; k < 1 + trial % 4; ++k) bad[rng() % bad.size()] = char(rng());
      try {
        read_all(c.format, bad);
      } catch (const Error&) {}
    }
  }
}

TEST(BagErrors, ChunkWithBadCrcIsSkipped) {
  TempDir dir;
  const std::string path = dir / "crc.mcap";
  BagWriterOptions o;
  o.chunk_bytes = 1;  // one message per chunk
  auto w = open_bag_writer(path, BagFormat::mcap, o);
  const uint32_t t = w->add_topic("/chatter", "std_msgs/msg/String");
  for (const char* s : {"first-message", "second-message", "third-message"}) w->write(t, 1, s);
  w->close();
  std::string bytes = read_file(path);
  bytes[bytes.find("second-message")] = 'S';
  for (bool summary : {true, false}) {
    std::string b = bytes;
    if (!summary) b.resize(b.size() - 8);  // no trailing magic: read linearly
    auto bag = open_bag_bytes(BagFormat::mcap, b, "crc.mcap");
    auto cur = bag->read("/chatter");
    std::vector<std::string> got;
    for (BagMessage m; cur->next(m);) got.emplace_back(m.data);
    EXPECT_EQ(got, (std::vector<std::string>{"first-message", "third-message"}));
    const auto& w = bag->warnings();
    EXPECT_EQ(std::count_if(w.begin(), w.end(), [](const std::string& s) { return s.find("bad CRC") != s.npos; }), 1);
  }
}

TEST(BagErrors, UnknownCompressionIsNamed) {
  TempDir dir;
  struct Case {
    BagFormat format;
    Compression compression;
    std::string from, to, name;
  };
  for (const Case& k :
       {Case{BagFormat::mcap, Compression::zstd, std::string("\4\0\0\0zstd", 8), std::string("\4\0\0\0zzzz", 8), "zzzz"},
        Case{BagFormat::ros1, Compression::lz4, "compression=lz4", "compression=xz4", "xz4"}}) {
    const std::string path = dir / (k.format == BagFormat::mcap ? "c.mcap" : "c.bag");
    BagWriterOptions o;
    o.compression = k.compression;
    ScanBagWriter w(path, k.format, CloudLayout{}, o);
    w.write(make_scan(50, 1), 10.0);
    w.close();
    std::string bytes = read_file(path);
    const size_t at = bytes.find(k.from);
    ASSERT_NE(at, std::string::npos);
    bytes.replace(at, k.from.size(), k.to);
    try {
      read_all(k.format, bytes);
      ADD_FAILURE() << "no error";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("unknown compression '" + k.name + "'"), std::string::npos) << e.what();
    }
  }
}

}  // namespace
}  // namespace gcmap::test

namespace gcmap::test {
namespace {

// rosbag2's per-message zstd compression (compression_mode MESSAGE), and FILE mode refused by name.
TEST(BagErrors, Db3MessageCompression) {
  TempDir dir;
  const std::string bag = dir / "zbag";
  const PointCloud scan = make_scan(60, 4);
  {
    ScanBagWriter w(bag, BagFormat::db3, CloudLayout{});
    w.write(scan, 50.0);
    w.close();
  }
  const std::string db = bag + "/zbag_0.db3";
  sqlite3* h = nullptr;
  ASSERT_EQ(sqlite3_open(db.c_str(), &h), SQLITE_OK);
  sqlite3_stmt* get = nullptr;
  sqlite3_prepare_v2(h, "SELECT data FROM messages", -1, &get, nullptr);
  ASSERT_EQ(sqlite3_step(get), SQLITE_ROW);
  const std::string packed = compress(Compression::zstd, std::string(static_cast<const char*>(sqlite3_column_blob(get, 0)),
                                                                     size_t(sqlite3_column_bytes(get, 0))));
  sqlite3_finalize(get);
  sqlite3_stmt* put = nullptr;
  sqlite3_prepare_v2(h, "UPDATE messages SET data = ?", -1, &put, nullptr);
  sqlite3_bind_blob(put, 1, packed.data(), int(packed.size()), SQLITE_STATIC);
  ASSERT_EQ(sqlite3_step(put), SQLITE_DONE);
  sqlite3_finalize(put);
  sqlite3_close(h);
  std::string meta = read_file(bag + "/metadata.yaml");
  const std::string plain = "compression_format: \"\"\n  compression_mode: \"\"";
  ASSERT_NE(meta.find(plain), std::string::npos);
  for (const char* mode : {"MESSAGE", "FILE"}) {
    std::string m = meta;
    m.replace(m.find(plain), plain.size(), std::string("compression_format: zstd\n  compression_mode: ") + mode);
    write_file_atomic(bag + "/metadata.yaml", [&](std::ostream& o) { o << m; });
    if (std::string(mode) == "FILE") {
      EXPECT_THROW([&] { BagScanSource s(bag); }(), Error);
      continue;
    }
    BagScanSource src(bag);
    BagScan s;
    ASSERT_TRUE(src.next(s));
    EXPECT_EQ(s.cloud.points, finite_points(scan).points);
  }
  // The .db3 alone: its messages are compressed, but without metadata.yaml nothing says so.
  BagScanSource alone(db);
  BagScan s;
  EXPECT_FALSE(alone.next(s));
  EXPECT_EQ(alone.skipped(), 1u);
}

}  // namespace
}  // namespace gcmap::test
