#pragma once
// The run-quality report (quality.json, report.html): why a map may be bad, from what the run
// computed, without ground truth. Per frame the odometry's registration figures, per submap how
// well it agrees with the submaps it overlaps, every loop candidate, stamp anomalies, a verdict.
#include <string>
#include <vector>

#include "gcmap/io/json.hpp"
#include "gcmap/mapping/pipeline.hpp"

namespace gcmap {

// What the flags take (command-line options of gcmap map until they become a config section).
struct QualityThresholds {
  // A frame is degenerate when its translation conditioning (RegistrationQuality) is below this.
  double degenerate_conditioning = 0.05;
  // Two overlapping submaps disagree when re-registering one onto the other moves it more than
  // this many times the median shift of consecutive submaps (the run's own noise), and by at
  // least min_shift m.
  double inconsistent_factor = 4.0;
  double min_shift = 0.02;
  double pair_radius = 20.0;  // m between submap origins: pairs compared
  // A stamp interval over this many times the median one (or not increasing) is an anomaly.
  double stamp_gap_factor = 1.5;
};

enum class WeakAxis { none, along_travel, across_travel, vertical };
const char* to_string(WeakAxis a);

struct FrameQualityRecord {
  int index = 0;
  MappingPipeline::FrameFigures figures;
  WeakAxis weak_axis = WeakAxis::none;
  bool failed = false, degenerate = false;
  double travelled = 0.0;  // m along the estimated trajectory from frame 0
};

struct SubmapPairRecord {
  int source = 0, target = 0;
  double shift = 0.0;  // m: how far registering source onto target moves it from the final estimate
  double rotation_deg = 0.0;
  double inlier_fraction = 0.0;
  bool inconsistent = false;
};

struct SubmapQualityRecord {
  int id = 0, first_frame = 0, last_frame = 0;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  // origin, output frame
  double entropy = 0.0;                                // mean map entropy of its cloud (eval/map_entropy)
  double worst_shift = 0.0;                            // m, over its pairs with non-consecutive submaps
  bool inconsistent = false;
};

struct StampAnomaly {
  int frame = 0;
  double interval = 0.0;  // s to the frame before
};

struct QualityReport {
  QualityThresholds thresholds;
  std::vector<FrameQualityRecord> frames;
  std::vector<SubmapQualityRecord> submaps;
  std::vector<SubmapPairRecord> pairs;
  double consecutive_shift = 0.0;  // m: median over consecutive submap pairs (the noise)
  std::vector<LoopRecord> loops;
  std::vector<StampAnomaly> stamp_anomalies;
  std::vector<std::string> verdict;  // sentences, most important first
};

// Everything from a finished pipeline; re-registers overlapping submap pairs (parallel).
QualityReport assess_quality(const MappingPipeline& pipeline, const QualityThresholds& thresholds = {});
Json quality_json(const QualityReport& report);

}  // namespace gcmap
