#pragma once
#include <string>
#include <vector>

#include "gcmap/core/scan_source.hpp"
#include "gcmap/io/input_assumptions.hpp"

namespace gcmap {

// Scan files of a sequence in file-name order: DIR/velodyne/*.bin for a KITTI layout, otherwise
// every .bin/.pcd/.ply in DIR. Throws Error when the folder is missing or holds no scans.
std::vector<std::string> list_scan_files(const std::string& dir);

// True when DIR looks like a KITTI sequence folder (has velodyne/).
bool is_kitti_layout(const std::string& dir);

// A sequence folder as a scan source, as decide_input (input_assumptions.hpp) found it: the
// scans, their stamps (a times file, or the assumed rate) and, beside them when present,
// labels/NNNNNN.label (SemanticKITTI, into PointCloud::labels) and point_times/NNNNNN.bin (float32
// per point, seconds relative to the scan's stamp, which is the start of the sweep; into
// PointCloud::times). A sidecar whose count does not match is ignored with a warning.
class FolderScanSource : public ScanSource {
 public:
  // Scans [start, start + max_frames) (max_frames 0: all). Throws Error naming --start when the
  // folder has no scan at start.
  FolderScanSource(const std::string& dir, int start = 0, int max_frames = 0);
  FolderScanSource(const InputAssumptions& input, int start, int max_frames, BinFields bin_fields = BinFields::xyzi);
  std::optional<ScanRecord> next() override;
  size_t size_hint() const override { return files_.size(); }

  // KITTI's own recordings, by decide_input's evidence.
  bool kitti_hdl64() const { return kitti_hdl64_; }
  int start() const { return start_; }
  // Stamp of scan i of this source.
  double stamp(size_t i) const;

 private:
  std::string root_;  // where labels/ and point_times/ are
  std::vector<std::string> files_;
  std::vector<double> stamps_;  // of the whole folder
  int start_ = 0;
  size_t next_ = 0;
  bool kitti_hdl64_ = false;
  BinFields bin_fields_ = BinFields::xyzi;
};

}  // namespace gcmap
