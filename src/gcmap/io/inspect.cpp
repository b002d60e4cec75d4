#include "gcmap/io/inspect.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>

#include "gcmap/core/error.hpp"
#include "gcmap/core/timer.hpp"
#include "gcmap/io/bag_scans.hpp"
#include "gcmap/io/file.hpp"
#include "gcmap/io/point_cloud_io.hpp"

namespace gcmap {

namespace fs = std::filesystem;

namespace {

double percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  const size_t k = std::min(v.size() - 1, static_cast<size_t>(q * (v.size() - 1) + 0.5));
  std::nth_element(v.begin(), v.begin() + k, v.end());
  return v[k];
}

double wrap(double a) { return std::remainder(a, 2.0 * M_PI); }

bool valid(const Eigen::Vector3f& p) { return p.allFinite() && p.squaredNorm() > 1e-6f; }

// Rings from the point order: a ring-ordered scan (KITTI's .bin) wraps around in azimuth once per
// ring, always the same way; points jittering about the wrap angle jump back and forth and cancel.
int rings_from_order(const PointCloud& c) {
  long up = 0, down = 0;
  size_t n = 0;
  double prev = 0;
  for (const auto& p : c.points) {
    if (!valid(p)) continue;
    const double az = std::atan2(p.y(), p.x());
    if (n++ && az - prev > M_PI) ++up;
    if (n > 1 && prev - az > M_PI) ++down;
    prev = az;
  }
  const long wraps = std::labs(up - down);
  return n && up + down < static_cast<long>(n / 200) ? static_cast<int>(wraps) + 1 : 0;
}

// Rings from the elevation histogram (0.1 deg bins): separate peaks, or one smear (no rings).
void rings_from_elevation(const std::vector<double>& elevations, ScanShape& s) {
  const double bin = 0.1;
  std::vector<size_t> hist(1800, 0);
  for (double e : elevations) ++hist[std::clamp(static_cast<int>((e + 90.0) / bin), 0, 1799)];
  const size_t min_count = std::max<size_t>(3, elevations.size() / 2000);
  size_t occupied = 0, span_bins = 0;
  int first = -1, last = -1;
  for (int b = 0; b < 1800; ++b) {
    if (hist[b] < min_count) continue;
    if (first < 0) first = b;
    last = b;
    ++occupied;
  }
  if (first < 0) return;
  span_bins = last - first + 1;
  if (occupied > 0.6 * span_bins) return;  // a smear: non-repetitive, or a ring per bin
  double sum = 0, weight = 0;
  for (int b = last; b >= first - 1; --b) {
    if (b >= first && hist[b] >= min_count) {
      sum += hist[b] * (b * bin - 90.0 + bin / 2);
      weight += hist[b];
    } else if (weight > 0) {
      s.elevations_deg.push_back(sum / weight);
      sum = weight = 0;
    }
  }
}

}  // namespace

ScanShape scan_shape(const PointCloud& cloud) {
  ScanShape s;
  std::vector<double> elevations;
  std::vector<bool> sector(36, false);
  elevations.reserve(cloud.size());
  for (const auto& p : cloud.points) {
    if (!valid(p)) continue;
    elevations.push_back(std::atan2(p.z(), std::hypot(p.x(), p.y())) * 180.0 / M_PI);
    sector[std::clamp(static_cast<int>((std::atan2(p.y(), p.x()) + M_PI) / (2 * M_PI) * 36), 0, 35)] = true;
  }
  if (elevations.empty()) return s;
  s.spinning = std::all_of(sector.begin(), sector.end(), [](bool b) { return b; });
  s.elevation_min_deg = percentile(elevations, 0.005);
  s.elevation_max_deg = percentile(elevations, 0.995);
  rings_from_elevation(elevations, s);
  const int ordered = rings_from_order(cloud);
  if (ordered >= 4) {
    s.rings = ordered;
    s.ring_evidence = "azimuth wraps in point order";
  } else if (!s.elevations_deg.empty()) {
    s.rings = static_cast<int>(s.elevations_deg.size());
    s.ring_evidence = "peaks of the elevation histogram";
  } else {
    s.ring_evidence = "no rings: elevations spread evenly (non-repetitive pattern or unordered points)";
  }
  return s;
}

PointTimeCheck check_point_times(const std::vector<float>& times, double offset, double interval) {
  PointTimeCheck c;
  c.offset = offset;
  if (times.empty()) return c;
  const auto [lo, hi] = std::minmax_element(times.begin(), times.end());
  c.min = *lo;
  c.max = *hi;
  if (!(interval > 0)) interval = 0.1;
  const double span = c.max - c.min, far = std::max(1.0, 10.0 * interval);
  char buf[256];
  auto unit = [&](double scale) { return span / scale > 0.1 * interval && span / scale < 5.0 * interval; };
  if (span == 0.0) {
    c.all_zero = offset == 0.0 && c.min == 0.0;
    c.mistake = "zero";
    std::snprintf(buf, sizeof buf, "per-point times are all %s: nothing to deskew with (a driver that fills no times?)",
                  c.all_zero ? "zero" : "equal");
  } else if (span > 20.0 * interval && (unit(1e3) || unit(1e6) || unit(1e9))) {
    c.mistake = unit(1e3) ? "milliseconds" : unit(1e6) ? "microseconds" : "nanoseconds";
    std::snprintf(buf, sizeof buf,
                  "per-point times span %.6g s against a scan interval of %.3g s: %s where seconds are expected?", span, interval,
                  c.mistake.c_str());
  } else if (std::abs(offset) > far || std::abs(c.min) > far) {
    c.mistake = "absolute";
    std::snprintf(buf, sizeof buf,
                  "per-point times lie %.6g s from the scan's stamp: absolute times where times relative to it are expected?",
                  std::abs(offset) > far ? offset : c.min);
  } else if (offset + c.max <= 0.1 * span && offset + c.min < -0.5 * span) {
    c.mistake = "sweep_end";
    std::snprintf(buf, sizeof buf, "the recording stamps the end of the sweep (points from %.4f to %.4f s after the stamp)%s",
                  offset + c.min, offset + c.max, offset != 0.0 ? "; gcmap stamps each scan at its earliest point instead" : "");
  }
  if (!c.mistake.empty()) c.message = buf;
  return c;
}

namespace {

// What the sample of scans adds up to.
struct Sample {
  std::vector<double> ranges, intensities, interval_samples;
  std::vector<size_t> points;
  std::vector<PointTimeCheck> checks;
  double rotation = 0, rotation_time = 0;
  size_t most_points = 0;
};

// Total azimuth turned over the scan's time span, from the circular mean azimuth of 32 time bins.
void add_sweep(const PointCloud& c, Sample& s) {
  if (!c.has_times() || c.times.size() != c.size()) return;
  const auto [lo, hi] = std::minmax_element(c.times.begin(), c.times.end());
  const double t0 = *lo, span = *hi - *lo;
  if (!(span > 0)) return;
  std::vector<double> sx(32, 0), sy(32, 0);
  for (size_t i = 0; i < c.size(); ++i) {
    const auto& p = c.points[i];
    const int b = std::min(31, static_cast<int>((c.times[i] - t0) / span * 32));
    const double n = std::hypot(p.x(), p.y());
    if (n > 1e-3) sx[b] += p.x() / n, sy[b] += p.y() / n;
  }
  int prev = -1;
  for (int b = 0; b < 32; ++b) {
    if (std::hypot(sx[b], sy[b]) < 1e-6) continue;
    if (prev >= 0) s.rotation += wrap(std::atan2(sy[b], sx[b]) - std::atan2(sy[prev], sx[prev]));
    if (prev >= 0) s.rotation_time += (b - prev) * span / 32;
    prev = b;
  }
}

void add_points(const PointCloud& c, Sample& s, InspectReport& r) {
  size_t n = 0;
  for (size_t i = 0; i < c.size(); ++i) {
    const auto& p = c.points[i];
    if (!p.allFinite()) {
      ++r.nan_points;
      continue;
    }
    if (p.squaredNorm() == 0.f) {
      ++r.zero_points;
      continue;
    }
    ++n;
    s.ranges.push_back(p.norm());
    if (c.has_intensities()) s.intensities.push_back(c.intensities[i]);
  }
  s.points.push_back(n);
  r.intensities = r.intensities || c.has_intensities();
  ++r.sampled;
  if (n > s.most_points) {  // the sensor as its fullest scan shows it
    s.most_points = n;
    r.shape = scan_shape(c);
  }
  add_sweep(c, s);
}

// The raw scan with its non-finite points kept (read_point_cloud drops them).
PointCloud read_raw(const std::string& path, BinFields fields) {
  std::string ext = fs::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), ::tolower);
  const std::string bytes = read_file(path);
  if (ext == ".bin") return parse_bin(bytes, fields, path);
  if (ext == ".pcd") return parse_pcd(bytes, path);
  return parse_ply(bytes, path);
}

std::vector<size_t> sample_indices(size_t n, size_t k) {
  std::vector<size_t> out;
  if (n == 0 || k == 0) return out;
  k = std::min(n, k);
  for (size_t j = 0; j < k; ++j) out.push_back(k == 1 ? 0 : j * (n - 1) / (k - 1));
  return out;
}

void sample_folder(InspectReport& r, const InspectOptions& o, Sample& s) {
  const InputAssumptions& a = r.assumptions;
  const double interval = a.stamps.size() > 1 ? (a.stamps.back() - a.stamps.front()) / (a.stamps.size() - 1) : 0.1;
  for (size_t i : sample_indices(a.files.size(), o.sample_scans)) {
    PointCloud c;
    try {
      c = read_raw(a.files[i], o.input.bin_fields);
    } catch (const Error& e) {
      r.warnings.push_back(std::string("unreadable scan: ") + e.what());
      continue;
    }
    if (a.point_times) {
      const std::string side = (fs::path(a.root) / "point_times" / (fs::path(a.files[i]).stem().string() + ".bin")).string();
      std::error_code ec;
      if (fs::exists(side, ec)) {
        const std::string bytes = read_file(side);
        if (bytes.size() == c.size() * 4) {
          c.times.resize(c.size());
          std::memcpy(c.times.data(), bytes.data(), bytes.size());
          s.checks.push_back(check_point_times(c.times, 0.0, interval));
        }
      }
    }
    add_points(c, s, r);
  }
  r.time_field = a.point_times ? a.point_times_text.evidence + ", " + a.point_times_text.value : "none";
}

std::vector<double> sample_bag(InspectReport& r, const InspectOptions& o, Sample& s) {
  const InputAssumptions& a = r.assumptions;
  BagScanSource source(a.input, BagScanOptions{.topic = a.topic});
  r.time_field = a.point_times_text.value;
  const size_t n = source.message_count(), every = std::max<size_t>(1, n / std::max<size_t>(1, o.sample_scans));
  std::vector<double> stamps;
  BagScan scan;
  double prev_header = 0;
  for (size_t k = 0; source.next(scan); ++k) {
    stamps.push_back(scan.stamp);
    if (k % every) continue;
    const double interval = k ? scan.header_stamp - prev_header : 0.0;
    prev_header = scan.header_stamp;
    if (a.point_times) s.checks.push_back(check_point_times(scan.cloud.times, scan.stamp - scan.header_stamp, interval / every));
    add_points(scan.cloud, s, r);
  }
  if (source.skipped()) r.warnings.push_back(std::to_string(source.skipped()) + " messages could not be decoded");
  return stamps;
}

void add_stamp_stats(const std::vector<double>& stamps, InspectReport& r) {
  r.stamps = stamps.size();
  if (stamps.size() < 2) return;
  std::vector<double> dt;
  for (size_t k = 1; k < stamps.size(); ++k) {
    dt.push_back(stamps[k] - stamps[k - 1]);
    r.duplicates += dt.back() == 0.0;
    r.backwards += dt.back() < 0.0;
  }
  r.median_interval = percentile(dt, 0.5);
  r.rate_hz = r.median_interval > 0 ? 1.0 / r.median_interval : 0.0;
  std::vector<double> dev;
  for (double d : dt) dev.push_back(std::abs(d - r.median_interval));
  r.jitter = percentile(dev, 0.5);
  for (double d : dt) r.gaps += d > 1.5 * r.median_interval;
  r.largest_gap = *std::max_element(dt.begin(), dt.end());
  r.duration = stamps.back() - stamps.front();
  if (r.backwards) r.warnings.push_back(std::to_string(r.backwards) + " stamps go backwards");
  if (r.duplicates) r.warnings.push_back(std::to_string(r.duplicates) + " stamps repeat the previous one");
  if (r.gaps)
    r.warnings.push_back(std::to_string(r.gaps) + " gaps over 1.5 scan intervals (largest " + std::to_string(r.largest_gap) +
                         " s)");
}

void summarize(Sample& s, InspectReport& r) {
  r.range_p1 = percentile(s.ranges, 0.01);
  r.range_median = percentile(s.ranges, 0.5);
  r.range_p99 = percentile(s.ranges, 0.99);
  r.range_max = percentile(s.ranges, 1.0);
  r.intensity_min = percentile(s.intensities, 0.0);
  r.intensity_median = percentile(s.intensities, 0.5);
  r.intensity_max = percentile(s.intensities, 1.0);
  std::vector<double> pts(s.points.begin(), s.points.end());
  r.points_min = static_cast<size_t>(percentile(pts, 0.0));
  r.points_median = static_cast<size_t>(percentile(pts, 0.5));
  r.points_max = static_cast<size_t>(percentile(pts, 1.0));
  bool first = true;
  for (const PointTimeCheck& c : s.checks) {
    r.time_min = first ? c.min + c.offset : std::min(r.time_min, c.min + c.offset);
    r.time_max = first ? c.max + c.offset : std::max(r.time_max, c.max + c.offset);
    first = false;
  }
  for (const PointTimeCheck& c : s.checks)
    if (!c.mistake.empty()) {
      r.warnings.push_back(c.message);
      break;
    }
  r.sweep_direction = "none";
  if (std::abs(s.rotation) > M_PI && r.shape.spinning) {
    r.sweep_direction = s.rotation > 0 ? "counter-clockwise" : "clockwise";
    r.sweep_period = 2 * M_PI * s.rotation_time / std::abs(s.rotation);
  }
  if (r.nan_points)
    r.warnings.push_back(std::to_string(r.nan_points) + " non-finite points in the sampled scans (dropped when mapping)");
  if (r.zero_points)
    r.warnings.push_back(std::to_string(r.zero_points) +
                         " points at (0, 0, 0) in the sampled scans (no return; dropped by the range filter)");
}

}  // namespace

InspectReport inspect_recording(const std::string& input, const InspectOptions& options) {
  Stopwatch clock;
  InspectReport r;
  r.assumptions = decide_input(input, options.input);
  r.warnings = r.assumptions.warnings;
  Sample s;
  if (r.assumptions.layout == InputLayout::bag) {
    add_stamp_stats(sample_bag(r, options, s), r);
  } else {
    sample_folder(r, options, s);
    add_stamp_stats(r.assumptions.stamps, r);
  }
  summarize(s, r);
  r.seconds = clock.ms() / 1000.0;
  return r;
}

Json InspectReport::to_json() const {
  Json j = Json::object();
  j["assumptions"] = assumptions.to_json();
  Json st = Json::object();
  st["count"] = stamps;
  st["source"] = stamp_source_name(assumptions.stamp_source);
  st["rate_hz"] = rate_hz;
  st["median_interval_s"] = median_interval;
  st["jitter_s"] = jitter;
  st["duration_s"] = duration;
  st["gaps"] = gaps;
  st["largest_gap_s"] = largest_gap;
  st["duplicates"] = duplicates;
  st["backwards"] = backwards;
  j["stamps"] = st;
  Json pt = Json::object();
  pt["field"] = time_field;
  pt["min_s"] = time_min;
  pt["max_s"] = time_max;
  pt["sweep_direction"] = sweep_direction;
  pt["sweep_period_s"] = sweep_period;
  j["point_times"] = pt;
  Json se = Json::object();
  se["sampled_scans"] = sampled;
  se["rings"] = shape.rings;
  se["ring_evidence"] = shape.ring_evidence;
  Json el = Json::array();
  for (double e : shape.elevations_deg) el.push_back(e);
  se["ring_elevations_deg"] = el;
  se["elevation_min_deg"] = shape.elevation_min_deg;
  se["elevation_max_deg"] = shape.elevation_max_deg;
  se["pattern"] = shape.spinning ? "spinning" : shape.rings ? "rings, limited field of view" : "non-repetitive";
  se["points_per_scan"] = Json(Json::Array{Json(points_min), Json(points_median), Json(points_max)});
  se["range_m"] = Json(Json::Array{Json(range_p1), Json(range_median), Json(range_p99), Json(range_max)});
  se["intensity"] = intensities ? Json(Json::Array{Json(intensity_min), Json(intensity_median), Json(intensity_max)}) : Json();
  se["nan_points"] = nan_points;
  se["zero_points"] = zero_points;
  j["sensor"] = se;
  Json w = Json::array();
  for (const std::string& s : warnings) w.push_back(s);
  j["warnings"] = w;
  j["seconds"] = seconds;
  return j;
}

std::string InspectReport::text() const {
  std::string out;
  char buf[512];
  auto line = [&](const char* fmt, auto... args) {
    std::snprintf(buf, sizeof buf, fmt, args...);
    out += buf;
    out += "\n";
  };
  const InputAssumptions& a = assumptions;
  line("%s: %s, %s", a.input.c_str(), a.layout_text.value.c_str(), a.layout_text.evidence.c_str());
  line(
      "stamps: %zu, %s (%s); %.3f Hz (median interval %.4f s, jitter %.4f s), %.1f s; %zu gaps (largest %.3f s), %zu duplicates, "
      "%zu backwards",
      stamps, a.stamps_text.value.c_str(), a.stamps_text.evidence.c_str(), rate_hz, median_interval, jitter, duration, gaps,
      largest_gap, duplicates, backwards);
  if (time_field != "none")
    line("per-point times: %s; %.4f to %.4f s after the stamps gcmap uses; sweep %s%s", time_field.c_str(), time_min, time_max,
         sweep_direction.c_str(),
         sweep_period > 0 ? (", period " + std::to_string(sweep_period).substr(0, 6) + " s").c_str() : "");
  else line("per-point times: none (no deskewing unless preprocess.deskew_from_azimuth)");
  line("sensor (%zu scans sampled): %s, %d rings (%s), elevation %.1f to %.1f deg (%.1f deg field of view)", sampled,
       shape.spinning ? "spinning"
       : shape.rings  ? "rings, limited field of view"
                      : "non-repetitive",
       shape.rings, shape.ring_evidence.c_str(), shape.elevation_min_deg, shape.elevation_max_deg,
       shape.elevation_max_deg - shape.elevation_min_deg);
  line(
      "points per scan: %zu / %zu / %zu (min / median / max); range %.1f / %.1f / %.1f / %.1f m (1%% / median / 99%% / max); %zu "
      "NaN, %zu at zero",
      points_min, points_median, points_max, range_p1, range_median, range_p99, range_max, nan_points, zero_points);
  if (intensities) line("intensity: %.3g / %.3g / %.3g (min / median / max)", intensity_min, intensity_median, intensity_max);
  else line("intensity: none");
  out += "gcmap map will assume:\n";
  for (const std::string& l : a.lines())
    if (l.rfind("warning: ", 0) != 0) out += "  " + l + "\n";
  for (const std::string& w : warnings) out += "warning: " + w + "\n";
  line("(read in %.2f s)", seconds);
  return out;
}

}  // namespace gcmap
