#include "gcmap/io/sequence.hpp"

#include <algorithm>
#include <filesystem>

#include "gcmap/core/error.hpp"

namespace gcmap {

namespace fs = std::filesystem;

bool is_kitti_layout(const std::string& dir) {
  std::error_code ec;
  return fs::is_directory(fs::path(dir) / "velodyne", ec);
}

std::vector<std::string> list_scan_files(const std::string& dir) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) throw Error(dir + ": not a folder");
  const fs::path root = is_kitti_layout(dir) ? fs::path(dir) / "velodyne" : fs::path(dir);
  std::vector<std::string> files;
  for (const auto& e : fs::directory_iterator(root, ec)) {
    if (!e.is_regular_file()) continue;
    std::string ext = e.path().extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), ::tolower);
    if (ext == ".bin" || ext == ".pcd" || ext == ".ply") files.push_back(e.path().string());
  }
  if (ec) throw Error(dir + ": cannot list (" + ec.message() + ")");
  std::sort(files.begin(), files.end());
  if (files.empty()) throw Error(root.string() + ": no .bin, .pcd or .ply scans");
  return files;
}

}  // namespace gcmap
