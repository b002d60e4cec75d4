#pragma once
#include <string>
#include <vector>

namespace gcmap {

// Scan files of a sequence in file-name order: DIR/velodyne/*.bin for a KITTI layout, otherwise
// every .bin/.pcd/.ply in DIR. Throws Error when the folder is missing or holds no scans.
std::vector<std::string> list_scan_files(const std::string& dir);

// True when DIR looks like a KITTI sequence folder (has velodyne/).
bool is_kitti_layout(const std::string& dir);

}  // namespace gcmap
