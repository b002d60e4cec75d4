#pragma once
// LAS 1.4 point clouds (ASPRS LAS 1.4 R15), point data record format 6, or 7 when the points have
// colours: what survey and GIS tools read. Coordinates are doubles here (georeferenced values do
// not fit a float) and int32 on disk at a fixed 1 mm scale with offsets from the bounds.
#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "gcmap/core/point_cloud.hpp"

namespace gcmap {

inline constexpr double kLasScale = 0.001;  // m per coordinate step

// Channels are empty (written as 0) or of size().
struct LasCloud {
  std::vector<Eigen::Vector3d> points;
  std::vector<uint16_t> intensities;
  std::vector<double> gps_times;  // the input's clock (see LasWriteOptions::time_note)
  std::vector<uint8_t> classes;   // ASPRS classes
  std::vector<uint16_t> point_source_ids;
  std::vector<std::array<uint16_t, 3>> colors;  // red, green, blue in 0..65535: format 7 when not empty
  size_t size() const { return points.size(); }
};

struct LasHeader {
  int version_major = 1, version_minor = 4;
  int point_format = 6, record_length = 30;
  uint16_t global_encoding = 0;
  std::string system_identifier, generating_software;
  Eigen::Vector3d scale = Eigen::Vector3d::Constant(kLasScale), offset = Eigen::Vector3d::Zero();
  Eigen::Vector3d min = Eigen::Vector3d::Zero(), max = Eigen::Vector3d::Zero();
  uint64_t point_count = 0;
  std::array<uint64_t, 15> points_by_return{};
  std::string wkt;  // the OGC WKT VLR (record 2112); empty when no CRS is known
};

struct LasFile {
  LasHeader header;
  LasCloud cloud;
};

// How float intensities become LAS's uint16: unit multiplies values in [0, 1] by 65535 (KITTI);
// raw rounds and clamps to [0, 65535] (sensor counts, e.g. 0..255 from bags).
enum class IntensityScaling { unit, raw };
IntensityScaling parse_intensity_scaling(const std::string& name);  // "unit", "raw"; throws Error
// unit when every value lies in [0, 1], else raw.
IntensityScaling detect_intensity_scaling(const std::vector<float>& intensities);
std::vector<uint16_t> las_intensities(const std::vector<float>& intensities, IntensityScaling scaling);

// SemanticKITTI label (low 16 bits: class) -> ASPRS class; the table is in las_writer.cpp and in
// the export's documentation. Unknown classes give 1 (unclassified).
uint8_t asprs_class_from_semantic_kitti(uint32_t label);

// A PointCloud in LAS form: classes from SemanticKITTI labels when present (else 0, never
// classified), point source id `source_id`, GPS time `stamp` plus the per-point time when known.
LasCloud las_cloud(const PointCloud& cloud, const Eigen::Isometry3d& T_world_cloud, IntensityScaling scaling, uint16_t source_id,
                   double stamp);
void append(LasCloud& to, const LasCloud& from);

struct LasWriteOptions {
  std::string wkt;  // written as the OGC WKT VLR when not empty
  std::string system_identifier = "gcmap export";
};

// Writes `cloud` atomically as LAS 1.4 format 6 (7 with colours). Throws Error("PATH: ...") when
// the extent does not fit int32 steps of 1 mm or a channel has the wrong size.
void write_las(const std::string& path, const LasCloud& cloud, const LasWriteOptions& options = {});
// Splits into files of at most `max_points` (STEM_000.las, STEM_001.las, ... in point order; one
// file STEM.las when it fits); returns the paths written.
std::vector<std::string> write_las_tiles(const std::string& dir, const std::string& stem, const LasCloud& cloud,
                                         size_t max_points, const LasWriteOptions& options = {});

// Reads LAS 1.4 point formats 6 and 7 (colours of format 7 in `colors`); throws Error("PATH: ...") on anything
// malformed, truncated or of another version or format.
LasFile read_las(const std::string& path);
LasFile parse_las(const std::string& bytes, const std::string& name);

}  // namespace gcmap
