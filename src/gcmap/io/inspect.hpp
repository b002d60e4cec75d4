#pragma once
// `gcmap inspect`: what a recording holds, read from the recording itself (stamps of every scan,
// points of a sample of scans spread over it), and what `gcmap map` will assume about it.
#include <string>
#include <vector>

#include "gcmap/core/point_cloud.hpp"
#include "gcmap/io/input_assumptions.hpp"
#include "gcmap/io/json.hpp"

namespace gcmap {

// The sensor as one scan shows it.
struct ScanShape {
  int rings = 0;                                        // 0: none found (a non-repetitive pattern, or unordered points)
  std::string ring_evidence;                            // how they were counted
  std::vector<double> elevations_deg;                   // of the rings, top first (from the elevation histogram)
  double elevation_min_deg = 0, elevation_max_deg = 0;  // 0.5 and 99.5 percentiles
  bool spinning = false;                                // points cover the full circle of azimuths
};
ScanShape scan_shape(const PointCloud& cloud);

// Per-point times of one scan against the convention gcmap expects (seconds after the scan's
// stamp, the start of the sweep, spanning about one scan interval). offset: the stamp gcmap uses
// minus the recording's own stamp for the scan (bags: the header's), 0 for sidecar times.
struct PointTimeCheck {
  double min = 0, max = 0;  // s after the stamp gcmap uses
  double offset = 0;
  bool all_zero = false;
  std::string mistake;  // empty when none is seen: "milliseconds", "nanoseconds", "absolute", "sweep_end", "zero"
  std::string message;  // the mistake in words
};
PointTimeCheck check_point_times(const std::vector<float>& times, double offset, double interval);

struct InspectOptions {
  InputOptions input;
  size_t sample_scans = 20;  // scans whose points are read, spread over the recording
};

struct InspectReport {
  InputAssumptions assumptions;
  // Stamps of every scan.
  size_t stamps = 0;
  double rate_hz = 0, median_interval = 0, jitter = 0;  // jitter: median absolute deviation of the intervals, s
  double duration = 0, largest_gap = 0;
  size_t gaps = 0, duplicates = 0, backwards = 0;  // gaps: intervals over 1.5 x the median
  // Per-point times (of the sample).
  std::string time_field;             // as read, with its unit and convention, or "none"
  double time_min = 0, time_max = 0;  // s after the stamps gcmap uses
  double sweep_period = 0;            // s of one turn, spinning sensors
  std::string sweep_direction;        // "counter-clockwise", "clockwise" or "none"
  // Sensor (of the sample).
  ScanShape shape;
  size_t sampled = 0, points_min = 0, points_median = 0, points_max = 0, nan_points = 0, zero_points = 0;
  double range_p1 = 0, range_median = 0, range_p99 = 0, range_max = 0;
  double intensity_min = 0, intensity_median = 0, intensity_max = 0;
  bool intensities = false;
  std::vector<std::string> warnings;
  double seconds = 0;

  Json to_json() const;
  std::string text() const;  // for a person
};

// Throws Error naming the input when it cannot be read at all.
InspectReport inspect_recording(const std::string& input, const InspectOptions& options);

}  // namespace gcmap
