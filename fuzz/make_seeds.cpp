// Writes the seed corpora fuzz/corpus/<target>/ : small valid files, through gcmap's writers where it
// has one (binary PLY and PCD, trajectories, config, bags: bag_seeds.hpp) and by hand for the
// formats it only reads.
// Usage: gcmap_fuzz_seeds fuzz/corpus
#include <algorithm>
#include <bit>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>

#include "bag_seeds.hpp"
#include "gcmap/core/se3.hpp"
#include "gcmap/io/gnss_io.hpp"
#include "gcmap/io/point_cloud_io.hpp"
#include "gcmap/io/trajectory_io.hpp"
#include "gcmap/mapping/config.hpp"

namespace fs = std::filesystem;
using namespace gcmap;

namespace {

void write_bytes(const fs::path& path, const std::string& bytes) { std::ofstream(path, std::ios::binary) << bytes; }

template <typename T>
std::string raw(const T* v, size_t n) {
  return std::string(reinterpret_cast<const char*>(v), n * sizeof(T));
}

PointCloud cloud(bool with_intensity) {
  PointCloud c;
  for (int i = 0; i < 4; ++i) {
    c.points.emplace_back(1.5f * i, -0.5f * i, 2.0f + i);
    if (with_intensity) c.intensities.push_back(0.25f * i);
  }
  return c;
}

void bin_seeds(const fs::path& dir) {
  const float xyzi[8] = {1, 2, 3, 0.5f, -4, 5, -6, 0.25f}, xyz[6] = {1, 2, 3, 4, 5, 6};
  write_bytes(dir / "xyzi.bin", raw(xyzi, 8));
  write_bytes(dir / "xyz.bin", raw(xyz, 6));
}

void pcd_seeds(const fs::path& dir) {
  write_pcd((dir / "binary_xyzi.pcd").string(), cloud(true));
  write_pcd((dir / "binary_xyz.pcd").string(), cloud(false));
  write_bytes(dir / "ascii.pcd",
              "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z intensity rgb\nSIZE 4 4 8 4 4\nTYPE F F F F U\nCOUNT 1 1 1 1 1\n"
              "WIDTH 3\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 3\nDATA ascii\n1 2 3 0.5 255\n4 5 6 nan 0\n-1e3 7 8.5 1 7\n");
  // binary_compressed, column-major x x, y y, z z: an LZF literal run of the first float, a back
  // reference (length 4, distance 4) repeating it, then a literal run of the other 16 bytes.
  const float cols[6] = {1, 1, 2, 2, 3, 3};
  const std::string payload = raw(cols, 6);
  const std::string lzf = "\x03" + payload.substr(0, 4) + "\x40\x03" + "\x0f" + payload.substr(8);
  const uint32_t sizes[2] = {static_cast<uint32_t>(lzf.size()), static_cast<uint32_t>(payload.size())};
  write_bytes(dir / "compressed.pcd",
              "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 2\nHEIGHT 1\nPOINTS 2\n"
              "DATA binary_compressed\n" +
                  raw(sizes, 2) + lzf);
}

void ply_seeds(const fs::path& dir) {
  write_ply((dir / "binary_le_xyzi.ply").string(), cloud(true));
  write_ply((dir / "binary_le_xyz.ply").string(), cloud(false));
  write_bytes(dir / "ascii.ply",
              "ply\nformat ascii 1.0\ncomment seed\nelement vertex 2\nproperty double z\nproperty float x\n"
              "property uchar red\nproperty float y\nproperty float intensity\nelement face 1\n"
              "property list uchar int vertex_indices\nend_header\n3 1 255 2 0.5\n6 4 0 5 1\n3 0 1 2\n");
  std::string body;
  for (float v : {1.f, 2.f, 3.f, -4.f, 5.f, 6.5f}) {
    std::string b = raw(&v, 1);
    std::reverse(b.begin(), b.end());
    body += b;
  }
  write_bytes(dir / "binary_be.ply",
              "ply\nformat binary_big_endian 1.0\nelement camera 1\nproperty short id\nelement vertex 2\n"
              "property float x\nproperty float y\nproperty float z\nend_header\n\x01\x02" +
                  body);
}

void trajectory_seeds(const fs::path& dir) {
  Trajectory t;
  for (int i = 0; i < 3; ++i) {
    Vector6d xi;
    xi << 0.01 * i, -0.02 * i, 0.3 * i, 1.0 * i, 0.5 * i, -0.1 * i;
    t.poses.push_back(se3_exp(xi));
    t.stamps.push_back(1.5 + 0.1 * i);
    t.names.push_back("v" + std::to_string(i));
  }
  for (const auto& [format, name] : {std::pair{TrajectoryFormat::kitti, "kitti.txt"}, std::pair{TrajectoryFormat::tum, "tum.txt"},
                                     std::pair{TrajectoryFormat::named, "graph.txt"}}) {
    t.format = format;
    write_trajectory((dir / name).string(), t);
  }
  write_bytes(dir / "calib.txt", "P0: 1 0 0 0 0 1 0 0 0 0 1 0\nTr: 0 -1 0 0.1 0 0 -1 -0.05 1 0 0 -0.3\n");
}

void label_seeds(const fs::path& dir) {
  const uint32_t labels[4] = {40, 252 | (7u << 16), 10, 259};
  write_bytes(dir / "four.label", std::string(1, '\x01') + raw(labels, 4));
}

void config_seeds(const fs::path& dir) {
  write_bytes(dir / "default.yaml", MappingConfig{}.to_yaml());
  write_bytes(dir / "partial.yaml",
              "# comment\nglobal:\n  mode: sliding-window\n  window: 3\nloop: {enabled: false, rings: 10}\n");
}

// gnss.txt (first byte 0) and a NavSatFix message in ROS 1 (1) and CDR (2).
void gnss_seeds(const fs::path& dir) {
  write_bytes(dir / "gnss.txt", std::string(1, '\0') +
                                    "# stamp lat lon alt se sn su\n0.0 48.1 11.5 520.25 0.015 0.015 0.025\n"
                                    "0.1 48.1000001 11.5000002 520.3 2 2.5 3\n");
  NavSatFixMsg m;
  m.stamp_ns = 1700000000123456789;
  m.frame_id = "gps";
  m.latitude = 48.1, m.longitude = 11.5, m.altitude = 520.0;
  m.position_covariance = {0.0004, 0, 0, 0, 0.0004, 0, 0, 0, 0.0009};
  m.covariance_type = NavSatCovariance::diagonal_known;
  write_bytes(dir / "fix_ros1", std::string(1, '\1') + encode_navsatfix(m, MessageEncoding::ros1));
  write_bytes(dir / "fix_cdr", std::string(1, '\2') + encode_navsatfix(m, MessageEncoding::cdr));
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::cerr << "usage: " << argv[0] << " CORPUS_DIR\n";
    return 2;
  }
  const fs::path root = argv[1];
  const std::pair<const char*, void (*)(const fs::path&)> targets[] = {
      {"fuzz_kitti_bin", bin_seeds}, {"fuzz_pcd", pcd_seeds},
      {"fuzz_ply", ply_seeds},       {"fuzz_trajectory", trajectory_seeds},
      {"fuzz_labels", label_seeds},  {"fuzz_config", config_seeds},
      {"fuzz_gnss", gnss_seeds}};
  for (const auto& [name, make] : targets) {
    fs::create_directories(root / name);
    make(root / name);
  }
  fuzz::write_bag_seeds(root.string());
  return 0;
}
