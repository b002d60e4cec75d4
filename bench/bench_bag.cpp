// Read throughput of the bag readers: a generated drive of 150 scans x 32k points (x y z intensity t,
// 20 bytes a point, 96 MB of points) written in each container and compression, then read as scans
// (decode + conversion) and as raw messages, against reading the file's bytes. Not a test.
// Usage: bench_bag [DIR [SCANS [FORMAT...]]] (default: the system temp folder, 150 scans, every format). Peak RSS while reading
// the scans is measured from a reset (Linux /proc/self/clear_refs): run with more SCANS to see that it
// does not grow with the file.
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>

#include "gcmap/core/timer.hpp"
#include "gcmap/io/bag_scans.hpp"

using namespace gcmap;
namespace fs = std::filesystem;

namespace {

PointCloud make_scan(size_t n, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-50.f, 50.f);
  PointCloud c;
  for (size_t i = 0; i < n; ++i) {
    // Spinning-sensor-like: neighbouring points are close, which gives compressors their usual chance.
    const float a = float(i) * 6.2831853f / float(n), r = 10.f + float(i % 64) * 0.5f + u(rng) * 0.01f;
    c.points.emplace_back(r * std::cos(a), r * std::sin(a), float(i % 64) * 0.1f - 2.f);
    c.intensities.push_back(float(rng() % 256));
    c.times.push_back(0.1f * float(i) / float(n));
  }
  return c;
}

double file_read_mb_s(const std::string& path, uint64_t bytes) {
  Stopwatch w;
  std::ifstream in(path, std::ios::binary);
  std::vector<char> buf(1 << 20);
  while (in.read(buf.data(), std::streamsize(buf.size())) || in.gcount() > 0) {}
  return double(bytes) / 1e6 / (w.lap_ms() * 1e-3);
}

void reset_peak_rss() { std::ofstream("/proc/self/clear_refs") << "5"; }

double peak_rss_mb() {
  std::ifstream in("/proc/self/status");
  for (std::string line; std::getline(in, line);)
    if (line.rfind("VmHWM:", 0) == 0) return std::stod(line.substr(6)) / 1024.0;
  return 0;
}

uint64_t bag_bytes(const std::string& path) {
  if (!fs::is_directory(path)) return fs::file_size(path);
  uint64_t n = 0;
  for (const auto& e : fs::directory_iterator(path)) n += fs::file_size(e.path());
  return n;
}

}  // namespace

int main(int argc, char** argv) {
  const fs::path dir = argc > 1 ? fs::path(argv[1]) : fs::temp_directory_path() / "gcmap_bench_bag";
  fs::create_directories(dir);
  const int num_scans = argc > 2 ? std::max(1, std::atoi(argv[2])) : 150;
  const size_t points = 32768;
  std::vector<PointCloud> scans;
  for (int k = 0; k < 8; ++k) scans.push_back(make_scan(points, k));
  struct Case {
    const char* name;
    BagFormat format;
    Compression compression;
  };
  const Case cases[] = {{"mcap", BagFormat::mcap, Compression::none},    {"mcap-zstd", BagFormat::mcap, Compression::zstd},
                        {"mcap-lz4", BagFormat::mcap, Compression::lz4}, {"ros1", BagFormat::ros1, Compression::none},
                        {"ros1-lz4", BagFormat::ros1, Compression::lz4}, {"ros1-bz2", BagFormat::ros1, Compression::bz2},
                        {"db3", BagFormat::db3, Compression::none}};
  std::printf("%-10s %9s %9s %12s %12s %10s %12s %10s %10s\n", "format", "file MB", "write s", "raw MB/s", "scans MB/s",
              "scans/s", "file MB/s", "rss0 MB", "read MB");
  for (const Case& c : cases) {
    if (argc > 3 && std::find_if(argv + 3, argv + argc, [&](const char* a) { return std::string(a) == c.name; }) == argv + argc)
      continue;
    const std::string path = (dir / (std::string(c.name) + (c.format == BagFormat::db3    ? ""
                                                            : c.format == BagFormat::mcap ? ".mcap"
                                                                                          : ".bag")))
                                 .string();
    BagWriterOptions o;
    o.compression = c.compression;
    o.chunk_bytes = 4 << 20;
    Stopwatch w;
    {
      ScanBagWriter writer(path, c.format, CloudLayout{}, o);
      for (int k = 0; k < num_scans; ++k) writer.write(scans[k % scans.size()], 1000.0 + 0.1 * k);
      writer.close();
    }
    const double write_s = w.lap_ms() * 1e-3;
    const uint64_t bytes = bag_bytes(path);
    w.lap_ms();
    auto bag = open_bag(path);
    uint64_t payload = 0;
    auto cur = bag->read("/points");
    for (BagMessage m; cur->next(m);) payload += m.data.size();
    const double raw_s = w.lap_ms() * 1e-3;
    cur.reset();
    bag.reset();
    reset_peak_rss();
    const double rss0 = peak_rss_mb();
    w.lap_ms();
    BagScanSource src(path);
    size_t n = 0;
    for (BagScan s; src.next(s);) n += s.cloud.size() > 0;
    const double scan_s = w.lap_ms() * 1e-3, read_rss = peak_rss_mb();
    std::printf("%-10s %9.1f %9.2f %12.0f %12.0f %10.1f %12.0f %10.0f %10.0f\n", c.name, bytes / 1e6, write_s,
                bytes / 1e6 / raw_s, bytes / 1e6 / scan_s, n / scan_s,
                file_read_mb_s(c.format == BagFormat::db3 ? path + "/" + c.name + "_0.db3" : path, bytes), rss0, read_rss);
    std::fflush(stdout);
    fs::remove_all(path);
  }
  fs::remove_all(dir);
}
