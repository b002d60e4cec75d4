#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <limits>
#include <utility>

#include "gcmap/core/error.hpp"
#include "gcmap/io/file.hpp"
#include "gcmap/io/las.hpp"

namespace gcmap {
namespace {

constexpr int kHeaderSize = 375, kVlrHeaderSize = 54;
constexpr size_t kBlockPoints = 1 << 16;  // encoded in parallel, then written

// Format 6, or 7 with its red, green and blue.
int record_length(const LasCloud& c) { return c.colors.empty() ? 30 : 36; }

// SemanticKITTI class -> ASPRS class. ASPRS 0-22 are standard; 64 vehicle, 65 person (riders too),
// 66 fence, 67 pole, 68 traffic sign are user-definable classes (64-255) the export documents.
// Moving classes (252-259) map as their static counterparts.
constexpr std::pair<uint16_t, uint8_t> kAsprsFromSemanticKitti[] = {
    {1, 7},                                                                     // outlier: low noise
    {10, 64},  {11, 64},  {13, 64},  {15, 64},  {16, 64},  {18, 64}, {20, 64},  // vehicles
    {30, 65},  {31, 65},  {32, 65},                                             // person, bicyclist, motorcyclist
    {40, 11},  {44, 11},  {60, 11},                                             // road, parking, lane marking: road surface
    {48, 2},   {49, 2},                                                         // sidewalk, other ground: ground
    {50, 6},                                                                    // building
    {51, 66},                                                                   // fence
    {70, 5},   {71, 5},                                                         // vegetation, trunk: high vegetation
    {72, 3},                                                                    // terrain: low vegetation
    {80, 67},  {81, 68},                                                        // pole, traffic sign
    {252, 64}, {256, 64}, {257, 64}, {258, 64}, {259, 64},                      // moving vehicles
    {253, 65}, {254, 65}, {255, 65},                                            // moving bicyclist, person, motorcyclist
};

template <typename T>
void put(char* at, T value) {
  std::memcpy(at, &value, sizeof(T));  // little endian host (x86-64, aarch64)
}
void put_text(char* at, const std::string& text, size_t width) { std::memcpy(at, text.data(), std::min(text.size(), width)); }

std::string header_bytes(const LasHeader& h, uint32_t vlr_count, uint32_t data_offset) {
  std::string b(kHeaderSize, '\0');
  std::memcpy(b.data(), "LASF", 4);
  put<uint16_t>(&b[6], h.global_encoding);
  put<uint8_t>(&b[24], 1);
  put<uint8_t>(&b[25], 4);
  put_text(&b[26], h.system_identifier, 32);
  put_text(&b[58], h.generating_software, 32);
  const std::time_t now = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&now, &tm);
  put<uint16_t>(&b[90], tm.tm_yday + 1);
  put<uint16_t>(&b[92], tm.tm_year + 1900);
  put<uint16_t>(&b[94], kHeaderSize);
  put<uint32_t>(&b[96], data_offset);
  put<uint32_t>(&b[100], vlr_count);
  put<uint8_t>(&b[104], h.point_format);
  put<uint16_t>(&b[105], h.record_length);
  // Legacy counts (107, 111) stay 0: format 6 is not a legacy format.
  for (int k = 0; k < 3; ++k) {
    put<double>(&b[131 + 8 * k], h.scale[k]);
    put<double>(&b[155 + 8 * k], h.offset[k]);
    put<double>(&b[179 + 16 * k], h.max[k]);
    put<double>(&b[187 + 16 * k], h.min[k]);
  }
  put<uint64_t>(&b[247], h.point_count);
  for (int r = 0; r < 15; ++r) put<uint64_t>(&b[255 + 8 * r], h.points_by_return[r]);
  return b;
}

std::string wkt_vlr(const std::string& wkt) {
  const std::string payload = wkt + '\0';
  if (payload.size() > std::numeric_limits<uint16_t>::max())
    throw Error("WKT of " + std::to_string(payload.size()) + " bytes does not fit a VLR");
  std::string b(kVlrHeaderSize, '\0');
  put_text(&b[2], "LASF_Projection", 16);
  put<uint16_t>(&b[18], 2112);
  put<uint16_t>(&b[20], payload.size());
  put_text(&b[22], "OGC coordinate system WKT", 32);
  return b + payload;
}

// The coordinate of one axis in 1 mm steps from `offset`.
int32_t step(double value, double offset) { return static_cast<int32_t>(std::llround((value - offset) / kLasScale)); }

void check_sizes(const LasCloud& c, const std::string& path) {
  const auto bad = [&](size_t n) { return n != 0 && n != c.size(); };
  if (bad(c.intensities.size()) || bad(c.gps_times.size()) || bad(c.classes.size()) || bad(c.point_source_ids.size()) ||
      bad(c.colors.size()))
    throw Error(path + ": a LAS channel's size differs from the point count");
}

LasHeader make_header(const LasCloud& c, const LasWriteOptions& o, const std::string& path) {
  LasHeader h;
  h.global_encoding = 1 << 4;  // bit 4 (CRS as WKT) is required with formats 6-10; bit 0 clear: see gps_times
  h.system_identifier = o.system_identifier;
  h.generating_software = "gcmap " GCMAP_VERSION;
  h.wkt = o.wkt;
  h.point_format = c.colors.empty() ? 6 : 7;
  h.record_length = record_length(c);
  h.point_count = c.size();
  h.points_by_return[0] = c.size();
  if (c.size() == 0) return h;
  Eigen::AlignedBox3d box;
  for (const Eigen::Vector3d& p : c.points) box.extend(p);
  if (!box.min().allFinite() || !box.max().allFinite()) throw Error(path + ": a point is not finite");
  h.offset = box.center().array().round();
  const double reach = (box.max() - h.offset).cwiseMax(h.offset - box.min()).maxCoeff();
  if (reach / kLasScale > std::numeric_limits<int32_t>::max() - 1.0)
    throw Error(path + ": the map spans more than 4294 km, beyond int32 steps of 1 mm");
  for (int k = 0; k < 3; ++k) {  // the bounds of the stored (rounded) coordinates
    h.min[k] = step(box.min()[k], h.offset[k]) * kLasScale + h.offset[k];
    h.max[k] = step(box.max()[k], h.offset[k]) * kLasScale + h.offset[k];
  }
  return h;
}

void encode(const LasCloud& c, const Eigen::Vector3d& offset, size_t i, char* r) {
  std::memset(r, 0, record_length(c));
  for (int k = 0; k < 3; ++k) put<int32_t>(r + 4 * k, step(c.points[i][k], offset[k]));
  if (!c.intensities.empty()) put<uint16_t>(r + 12, c.intensities[i]);
  put<uint8_t>(r + 14, 0x11);  // return 1 of 1
  if (!c.classes.empty()) put<uint8_t>(r + 16, c.classes[i]);
  if (!c.point_source_ids.empty()) put<uint16_t>(r + 20, c.point_source_ids[i]);
  if (!c.gps_times.empty()) put<double>(r + 22, c.gps_times[i]);
  for (int k = 0; k < 3 && !c.colors.empty(); ++k) put<uint16_t>(r + 30 + 2 * k, c.colors[i][k]);
}

void write_records(std::ostream& out, const LasCloud& c, const Eigen::Vector3d& offset) {
  const size_t length = record_length(c);
  std::string block(std::min(c.size(), kBlockPoints) * length, '\0');
  for (size_t begin = 0; begin < c.size(); begin += kBlockPoints) {
    const size_t n = std::min(kBlockPoints, c.size() - begin);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 4096), [&](const tbb::blocked_range<size_t>& range) {
      for (size_t i = range.begin(); i != range.end(); ++i) encode(c, offset, begin + i, &block[i * length]);
    });
    out.write(block.data(), n * length);
  }
}

LasCloud slice(const LasCloud& c, size_t begin, size_t end) {
  const auto part = [&](const auto& v) {
    return v.empty() ? std::decay_t<decltype(v)>{} : std::decay_t<decltype(v)>(v.begin() + begin, v.begin() + end);
  };
  return {part(c.points), part(c.intensities), part(c.gps_times), part(c.classes), part(c.point_source_ids), part(c.colors)};
}

}  // namespace

IntensityScaling parse_intensity_scaling(const std::string& name) {
  if (name == "unit") return IntensityScaling::unit;
  if (name == "raw") return IntensityScaling::raw;
  throw Error("--intensity: expected unit or raw, got \"" + name + "\"");
}

IntensityScaling detect_intensity_scaling(const std::vector<float>& intensities) {
  const bool unit = std::all_of(intensities.begin(), intensities.end(), [](float v) { return v >= 0.0f && v <= 1.0f; });
  return unit ? IntensityScaling::unit : IntensityScaling::raw;
}

std::vector<uint16_t> las_intensities(const std::vector<float>& intensities, IntensityScaling scaling) {
  const double factor = scaling == IntensityScaling::unit ? 65535.0 : 1.0;
  std::vector<uint16_t> out(intensities.size());
  for (size_t i = 0; i < out.size(); ++i) {
    const double v = std::isfinite(intensities[i]) ? std::round(intensities[i] * factor) : 0.0;
    out[i] = static_cast<uint16_t>(std::clamp(v, 0.0, 65535.0));
  }
  return out;
}

uint8_t asprs_class_from_semantic_kitti(uint32_t label) {
  for (const auto& [semantic, asprs] : kAsprsFromSemanticKitti)
    if (semantic == (label & 0xffff)) return asprs;
  return 1;  // unlabeled, other-structure, other-object and unknown classes: unclassified
}

LasCloud las_cloud(const PointCloud& cloud, const Eigen::Isometry3d& T_world_cloud, IntensityScaling scaling, uint16_t source_id,
                   double stamp) {
  LasCloud out;
  out.points.resize(cloud.size());
  for (size_t i = 0; i < cloud.size(); ++i) out.points[i] = T_world_cloud * cloud.points[i].cast<double>();
  if (cloud.has_intensities()) out.intensities = las_intensities(cloud.intensities, scaling);
  out.gps_times.assign(cloud.size(), stamp);
  if (cloud.has_times())
    for (size_t i = 0; i < cloud.size(); ++i) out.gps_times[i] += cloud.times[i];
  out.classes.assign(cloud.size(), 0);
  if (cloud.has_labels())
    for (size_t i = 0; i < cloud.size(); ++i) out.classes[i] = asprs_class_from_semantic_kitti(cloud.labels[i]);
  out.point_source_ids.assign(cloud.size(), source_id);
  return out;
}

void append(LasCloud& to, const LasCloud& from) {
  const size_t before = to.size(), added = from.size();
  const auto join = [&](auto& a, const auto& b, auto fill) {
    if (a.empty() && b.empty()) return;
    a.resize(before, fill);
    if (b.empty()) a.resize(before + added, fill);
    else a.insert(a.end(), b.begin(), b.end());
  };
  join(to.intensities, from.intensities, uint16_t{0});
  join(to.gps_times, from.gps_times, 0.0);
  join(to.classes, from.classes, uint8_t{0});
  join(to.point_source_ids, from.point_source_ids, uint16_t{0});
  join(to.colors, from.colors, std::array<uint16_t, 3>{});
  to.points.insert(to.points.end(), from.points.begin(), from.points.end());
}

void write_las(const std::string& path, const LasCloud& cloud, const LasWriteOptions& options) {
  check_sizes(cloud, path);
  const LasHeader h = make_header(cloud, options, path);
  const std::string vlr = options.wkt.empty() ? std::string() : wkt_vlr(options.wkt);
  const std::string head = header_bytes(h, vlr.empty() ? 0 : 1, kHeaderSize + vlr.size());
  write_file_atomic(path, [&](std::ostream& out) {
    out << head << vlr;
    write_records(out, cloud, h.offset);
  });
}

std::vector<std::string> write_las_tiles(const std::string& dir, const std::string& stem, const LasCloud& cloud,
                                         size_t max_points, const LasWriteOptions& options) {
  namespace fs = std::filesystem;
  if (max_points == 0) throw Error("--max-points: must be > 0");
  if (cloud.size() <= max_points) {
    const std::string path = (fs::path(dir) / (stem + ".las")).string();
    write_las(path, cloud, options);
    return {path};
  }
  std::vector<std::string> paths;
  for (size_t begin = 0; begin < cloud.size(); begin += max_points) {
    char name[32];
    std::snprintf(name, sizeof(name), "_%03zu.las", paths.size());
    paths.push_back((fs::path(dir) / (stem + name)).string());
    write_las(paths.back(), slice(cloud, begin, std::min(cloud.size(), begin + max_points)), options);
  }
  return paths;
}

}  // namespace gcmap
