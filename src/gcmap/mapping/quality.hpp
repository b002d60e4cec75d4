#pragma once
// The run-quality report (quality.json, report.html): why a map may be bad, from what the run
// computed, without ground truth. Per frame the odometry's registration figures, per submap how
// well it agrees with the submaps it overlaps (against the noise its keyframes show among
// themselves), every loop candidate, stamp anomalies, a verdict. Thresholds: the quality: section.
#include <string>
#include <vector>

#include "gcmap/io/json.hpp"
#include "gcmap/mapping/pipeline.hpp"

namespace gcmap {

enum class WeakAxis { none, along_travel, across_travel, vertical };
const char* to_string(WeakAxis a);

struct FrameQualityRecord {
  int index = 0;  // the input's frame number (the run's plus QualityReport::frame_offset)
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
  bool coarse = false;  // registered at quality.coarse_resolution first (too little overlap at the final poses)
  double noise = 0.0;   // m: the noise of the two submaps' relative pose (mapping/quality.cpp)
  double limit = 0.0;   // m: the shift over which it is flagged (QualityConfig)
  bool inconsistent = false;
};

// Where a submap's noise comes from: its keyframes' disagreement (Submap::keyframe_noise), or, for
// a submap without that figure (one keyframe, loaded from a session), the consecutive submaps'.
enum class NoiseBaseline { keyframes, consecutive_submaps };
const char* to_string(NoiseBaseline b);

struct SubmapQualityRecord {
  int id = 0, first_frame = 0, last_frame = 0;         // the input's frame numbers
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  // origin, output frame
  double entropy = 0.0;                                // mean map entropy of its cloud (eval/map_entropy)
  double worst_shift = 0.0;                            // m, over its pairs with non-consecutive submaps
  double worst_ratio = 0.0;                            // the largest shift / limit of those pairs
  NoiseBaseline baseline = NoiseBaseline::keyframes;
  double keyframe_noise = 0.0;  // m: Submap::keyframe_noise (baseline keyframes)
  double noise = 0.0;           // m: of its pose, from keyframe_noise or the consecutive submaps' median shift
  bool inconsistent = false;
};

struct StampAnomaly {
  int frame = 0;          // the input's frame number
  double interval = 0.0;  // s to the frame before
};

struct QualityReport {
  QualityConfig thresholds;
  int frame_offset = 0;  // the input's number of the run's first frame (map --start)
  std::vector<FrameQualityRecord> frames;
  std::vector<SubmapQualityRecord> submaps;
  std::vector<SubmapPairRecord> pairs;
  double consecutive_shift = 0.0;  // m: median over consecutive submap pairs (the fallback noise)
  std::vector<LoopRecord> loops;
  std::vector<StampAnomaly> stamp_anomalies;
  std::vector<std::string> verdict;  // sentences, most important first
};

// Everything from a finished pipeline; re-registers overlapping submap pairs (parallel).
// frame_offset: added to every frame number, so that they are the input's (map --start).
QualityReport assess_quality(const MappingPipeline& pipeline, const QualityConfig& thresholds = {}, int frame_offset = 0);
Json quality_json(const QualityReport& report);

}  // namespace gcmap
