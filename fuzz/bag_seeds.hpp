#pragma once
// Seed corpora of the bag fuzz targets, written with the project's own bag writers: small bags of
// every container and compression, and single messages. make_seeds.cpp calls write_bag_seeds(dir).
#include <filesystem>
#include <fstream>
#include <string>

#include "gcmap/io/bag_scans.hpp"
#include "gcmap/io/file.hpp"

namespace gcmap::fuzz {

inline PointCloud seed_scan(int n, float t_span) {
  PointCloud c;
  for (int i = 0; i < n; ++i) {
    c.points.emplace_back(float(i % 7) - 3.f, float(i % 5) * 0.5f, float(i % 3) * 0.25f);
    c.intensities.push_back(float(i * 13 % 256));
    c.times.push_back(t_span * float(i) / float(n - 1));
  }
  return c;
}

inline void write_bag_seeds(const std::string& corpus) {
  namespace fs = std::filesystem;
  struct Seed {
    std::string target, name;
    BagFormat format;
    Compression compression;
    bool summary;
    PointTimeConvention time;
    uint32_t height;
  };
  using C = PointTimeConvention;
  const Seed seeds[] = {
      {"fuzz_bag_mcap", "plain.mcap", BagFormat::mcap, Compression::none, true, C::ouster_t, 1},
      {"fuzz_bag_mcap", "zstd.mcap", BagFormat::mcap, Compression::zstd, true, C::hesai_timestamp, 1},
      {"fuzz_bag_mcap", "lz4_organized.mcap", BagFormat::mcap, Compression::lz4, true, C::velodyne_time, 2},
      {"fuzz_bag_mcap", "nosummary.mcap", BagFormat::mcap, Compression::none, false, C::livox_custom_msg, 1},
      {"fuzz_bag_ros1", "plain.bag", BagFormat::ros1, Compression::none, true, C::sec_nsec, 1},
      {"fuzz_bag_ros1", "bz2.bag", BagFormat::ros1, Compression::bz2, true, C::livox_offset_time, 1},
      {"fuzz_bag_ros1", "lz4_livox.bag", BagFormat::ros1, Compression::lz4, true, C::livox_custom_msg, 1},
      {"fuzz_bag_db3", "plain.db3", BagFormat::db3, Compression::none, true, C::ouster_t, 2},
  };
  for (const Seed& s : seeds) {
    const fs::path dir = fs::path(corpus) / s.target;
    fs::create_directories(dir);
    BagWriterOptions o;
    o.compression = s.compression;
    o.mcap_summary = s.summary;
    o.chunk_bytes = 400;
    CloudLayout layout;
    layout.time = s.time;
    layout.height = s.height;
    const std::string path = (dir / s.name).string();
    const std::string out = s.format == BagFormat::db3 ? path + ".dir" : path;
    ScanBagWriter w(out, s.format, layout, o);
    w.write(seed_scan(12, 0.05f), 1700000000.0);
    w.write(seed_scan(8, 0.05f), 1700000000.1);
    w.close();
    if (s.format == BagFormat::db3) {
      fs::copy_file(fs::path(out) / (s.name + ".dir_0.db3"), path, fs::copy_options::overwrite_existing);
      fs::remove_all(out);
    }
  }
  // Single messages for fuzz_bag_messages: first byte bit 0 = Livox, bit 1 = CDR.
  const fs::path dir = fs::path(corpus) / "fuzz_bag_messages";
  fs::create_directories(dir);
  for (int kind = 0; kind < 4; ++kind) {
    CloudLayout layout;
    layout.time = kind & 1 ? C::livox_custom_msg : C::ouster_t;
    const std::string msg =
        encode_scan(seed_scan(6, 0.01f), 1.5, layout, kind & 2 ? MessageEncoding::cdr : MessageEncoding::ros1);
    write_file_atomic((dir / ("msg" + std::to_string(kind))).string(), [&](std::ostream& o) { o << char(kind) << msg; });
  }
}

}  // namespace gcmap::fuzz
