#include "gcmap/io/sequence.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <fstream>

#include "gcmap/core/error.hpp"
#include "gcmap/io/bag_reader.hpp"
#include "gcmap/io/file.hpp"
#include "gcmap/io/point_cloud_io.hpp"

namespace gcmap {

namespace fs = std::filesystem;

bool is_kitti_layout(const std::string& dir) {
  std::error_code ec;
  return fs::is_directory(fs::path(dir) / "velodyne", ec);
}

namespace {

bool is_scan_file(const fs::directory_entry& e) {
  if (!e.is_regular_file()) return false;
  std::string ext = e.path().extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), ::tolower);
  return ext == ".bin" || ext == ".pcd" || ext == ".ply";
}

// What to give instead of a folder without scans: the bags in it (e.g. what `gcmap simulate
// --format mcap` writes) or its subfolders that hold scans (a recording's export with its
// times.txt beside a `scans/`).
std::string what_is_there(const fs::path& dir) {
  std::error_code ec;
  std::string bags, folders;
  for (const auto& e : fs::directory_iterator(dir, ec)) {
    if (is_bag_path(e.path().string())) bags += (bags.empty() ? "" : ", ") + e.path().string();
    if (!e.is_directory(ec)) continue;
    size_t scans = 0;
    for (const auto& f : fs::directory_iterator(e.path(), ec)) scans += is_scan_file(f);
    if (scans) folders += (folders.empty() ? "" : ", ") + e.path().string() + " holds " + std::to_string(scans) + " scans";
  }
  if (!bags.empty()) return " (bags: " + bags + ")";
  if (!folders.empty()) return " (" + folders + ": give that folder)";
  return "";
}

}  // namespace

std::vector<std::string> list_scan_files(const std::string& dir) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) throw Error(dir + ": not a folder");
  const fs::path root = is_kitti_layout(dir) ? fs::path(dir) / "velodyne" : fs::path(dir);
  std::vector<std::string> files;
  for (const auto& e : fs::directory_iterator(root, ec))
    if (is_scan_file(e)) files.push_back(e.path().string());
  if (ec) throw Error(dir + ": cannot list (" + ec.message() + ")");
  std::sort(files.begin(), files.end());
  if (files.empty()) throw Error(root.string() + ": no .bin, .pcd or .ply scans" + what_is_there(dir));
  return files;
}

namespace {

// A sidecar of 4-byte values per point, or nothing (absent, or a count that does not match).
template <typename T>
std::vector<T> read_sidecar(const fs::path& path, size_t points) {
  std::error_code ec;
  if (!fs::exists(path, ec)) return {};
  const std::string bytes = read_file(path.string());
  if (bytes.size() != points * sizeof(T)) {
    spdlog::warn("{}: {} values for {} points, ignored", path.string(), bytes.size() / sizeof(T), points);
    return {};
  }
  std::vector<T> out(points);
  if (points) std::memcpy(out.data(), bytes.data(), bytes.size());
  return out;
}

}  // namespace

FolderScanSource::FolderScanSource(const std::string& dir, int start, int max_frames)
    : FolderScanSource(decide_input(dir, {}), start, max_frames) {}

FolderScanSource::FolderScanSource(const InputAssumptions& input, int start, int max_frames, BinFields bin_fields)
    : root_(input.root),
      files_(input.files),
      stamps_(input.stamps),
      start_(start),
      kitti_hdl64_(input.kitti_correction),
      bin_fields_(bin_fields) {
  if (start < 0) throw Error("--start: must be >= 0");
  if (max_frames < 0) throw Error("--max-frames: must be >= 0");
  if (start >= static_cast<int>(files_.size()))
    throw Error("--start " + std::to_string(start) + ": the sequence has " + std::to_string(files_.size()) + " scans");
  files_.erase(files_.begin(), files_.begin() + start);
  if (max_frames > 0 && static_cast<int>(files_.size()) > max_frames) files_.resize(max_frames);
}

double FolderScanSource::stamp(size_t i) const { return stamps_.at(i + start_); }

std::optional<ScanRecord> FolderScanSource::next() {
  if (next_ == files_.size()) return std::nullopt;
  const size_t i = next_++;
  ScanRecord r;
  r.stamp = stamp(i);
  r.load = [file = files_[i], dir = fs::path(root_), fields = bin_fields_] {
    PointCloud c = read_point_cloud(file, fields);
    const std::string stem = fs::path(file).stem().string();
    c.labels = read_sidecar<uint32_t>(dir / "labels" / (stem + ".label"), c.size());
    c.times = read_sidecar<float>(dir / "point_times" / (stem + ".bin"), c.size());
    return c;
  };
  return r;
}

}  // namespace gcmap
