#include "gcmap/mapping/quality.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "gcmap/eval/map_entropy.hpp"
#include "gcmap/mapping/report.hpp"
#include "gcmap/registration/registration.hpp"

namespace gcmap {

namespace {

// Weak directions within this angle (cosine) of an axis are named after it.
constexpr double kAxisCosine = 0.8;
// A degenerate stretch is reported from this many frames; gaps of up to kStretchGap frames join.
constexpr int kMinStretch = 3, kStretchGap = 2;
constexpr int kEntropyPoints = 20000;  // per submap: the entropy of a subsample (the cost is per point)
// m: submap clouds are voxel-downsampled, too sparse for the 0.3 m of a dense map.
constexpr double kEntropyRadius = 1.0;

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

std::string format(const char* fmt, auto... args) {
  char buf[256];
  std::snprintf(buf, sizeof buf, fmt, args...);
  return buf;
}

WeakAxis weak_axis(const RegistrationQuality& q, const Eigen::Vector3d& travel) {
  if (!q.registered || q.translation_information[2] <= 0.0) return WeakAxis::none;
  if (std::abs(q.weak_direction.z()) > kAxisCosine) return WeakAxis::vertical;
  if (travel.norm() > 1e-3 && std::abs(q.weak_direction.dot(travel.normalized())) > kAxisCosine) return WeakAxis::along_travel;
  return WeakAxis::across_travel;
}

std::vector<FrameQualityRecord> assess_frames(const MappingPipeline& p, const QualityConfig& t, int frame_offset) {
  const auto& odom = p.odometry();
  const auto traj = p.trajectory();
  std::vector<FrameQualityRecord> frames(p.frame_figures().size());
  double travelled = 0.0;
  for (size_t i = 0; i < frames.size(); ++i) {
    FrameQualityRecord& f = frames[i];
    f.index = static_cast<int>(i) + frame_offset;
    f.figures = p.frame_figures()[i];
    const RegistrationQuality& q = f.figures.registration;
    const Eigen::Vector3d travel =
        i > 0 ? Eigen::Vector3d((odom[i - 1].inverse() * odom[i]).translation()) : Eigen::Vector3d::Zero();
    if (i > 0) travelled += (traj[i].translation() - traj[i - 1].translation()).norm();
    f.travelled = travelled;
    f.weak_axis = weak_axis(q, travel);
    f.failed = q.failure != OdometryFailure::none;
    f.degenerate = q.registered && q.conditioning() < t.degenerate_conditioning;
  }
  return frames;
}

// Registers submap a onto b from their final relative pose: how far the pair's own data would move
// it. coarse_b: b's voxels at quality.coarse_resolution, registered on first (wider basin).
SubmapPairRecord compare_pair(const Mapper& m, int a, int b, const GaussianVoxelMap* coarse_b) {
  const Submap &sa = m.submaps()[a], &sb = m.submaps()[b];
  const Eigen::Isometry3d T_b_a = m.submap_pose(b).inverse() * m.submap_pose(a);
  RegistrationConfig reg;
  reg.max_iterations = 20;
  const Eigen::Isometry3d init = coarse_b ? align_vgicp(*sa.factor_source, *coarse_b, T_b_a, reg).T_target_source : T_b_a;
  const RegistrationResult r = align_vgicp(*sa.factor_source, *sb.voxels, init, reg);
  const Eigen::Isometry3d D = T_b_a.inverse() * r.T_target_source;
  SubmapPairRecord pair;
  pair.source = a, pair.target = b;
  pair.shift = D.translation().norm();
  pair.rotation_deg = rotation_angle(D) * 180.0 / M_PI;
  pair.inlier_fraction = sa.factor_source->empty() ? 0.0 : static_cast<double>(r.num_inliers) / sa.factor_source->size();
  pair.coarse = coarse_b != nullptr;
  return pair;
}

// The voxel maps at `resolution` of the targets of the given pairs (null for other submaps).
std::vector<std::shared_ptr<GaussianVoxelMap>> coarse_targets(const Mapper& m, const std::vector<std::pair<int, int>>& pairs,
                                                              double resolution) {
  std::vector<std::shared_ptr<GaussianVoxelMap>> maps(m.submaps().size());
  for (const auto& [a, b] : pairs) maps[b] = std::make_shared<GaussianVoxelMap>(resolution);
  tbb::parallel_for(size_t{0}, maps.size(), [&](size_t i) {
    if (!maps[i]) return;
    maps[i]->insert(*m.submaps()[i].cloud);
    maps[i]->finalize();
  });
  return maps;
}

// A pair that overlaps too little at its final poses may be a revisit that drifted by metres:
// registered again coarse to fine, it counts when it then overlaps (else it stays as it was).
void retry_coarse(const Mapper& m, const QualityConfig& t, const std::vector<std::pair<int, int>>& candidates,
                  std::vector<SubmapPairRecord>& pairs) {
  std::vector<size_t> retry;
  std::vector<std::pair<int, int>> retried;
  for (size_t k = 0; k < pairs.size(); ++k)
    if (pairs[k].inlier_fraction < t.min_pair_inliers) retry.push_back(k), retried.push_back(candidates[k]);
  const auto coarse = coarse_targets(m, retried, t.coarse_resolution);
  tbb::parallel_for(size_t{0}, retry.size(), [&](size_t i) {
    const auto [a, b] = retried[i];
    const SubmapPairRecord r = compare_pair(m, a, b, coarse[b].get());
    if (r.inlier_fraction >= t.min_pair_inliers) pairs[retry[i]] = r;
  });
}

std::vector<SubmapPairRecord> compare_pairs(const Mapper& m, const QualityConfig& t) {
  std::vector<std::pair<int, int>> candidates;
  const int n = static_cast<int>(m.submaps().size());
  for (int a = 0; a < n; ++a)
    for (int b = 0; b < a; ++b)
      if ((m.submap_pose(a).translation() - m.submap_pose(b).translation()).norm() < t.pair_radius) candidates.emplace_back(a, b);
  std::vector<SubmapPairRecord> pairs(candidates.size());
  tbb::parallel_for(size_t{0}, candidates.size(),
                    [&](size_t k) { pairs[k] = compare_pair(m, candidates[k].first, candidates[k].second, nullptr); });
  retry_coarse(m, t, candidates, pairs);
  return pairs;
}

// A submap's pose noise: its keyframes' disagreement averaged over its K keyframes (/sqrt(K)), or,
// without that figure, the consecutive submaps' median shift over sqrt(2) (a pair of two such
// submaps gets that median back). A pair's noise is that of the difference of its two
// submaps' poses, sqrt(na^2 + nb^2); it disagrees when its shift exceeds inconsistent_factor times
// that, and min_shift. On the simulator's small drive the keyframe-based noise of consecutive pairs
// is about half their median shift: the two measure the same thing.
void flag_pairs(QualityReport& r, const Mapper& m) {
  const QualityConfig& t = r.thresholds;
  std::vector<double> consecutive;
  for (const auto& p : r.pairs)
    if (p.source == p.target + 1 && p.inlier_fraction >= t.min_pair_inliers) consecutive.push_back(p.shift);
  r.consecutive_shift = median(consecutive);
  for (auto& s : r.submaps)
    s.noise = s.baseline == NoiseBaseline::keyframes ? s.noise / std::sqrt(m.submaps()[s.id].keyframes.size())
                                                     : r.consecutive_shift / std::sqrt(2.0);
  for (auto& p : r.pairs) {
    SubmapQualityRecord &s = r.submaps[p.source], &g = r.submaps[p.target];
    p.noise = std::hypot(s.noise, g.noise);
    p.limit = std::max(t.min_shift, t.inconsistent_factor * p.noise);
    const bool counted = p.source > p.target + 1 && p.inlier_fraction >= t.min_pair_inliers;
    p.inconsistent = counted && p.shift > p.limit;
    if (!counted) continue;
    for (SubmapQualityRecord* x : {&s, &g}) {
      x->worst_shift = std::max(x->worst_shift, p.shift);
      x->worst_ratio = std::max(x->worst_ratio, p.shift / p.limit);
      x->inconsistent = x->inconsistent || p.inconsistent;
    }
  }
}

std::vector<SubmapQualityRecord> assess_submaps(const Mapper& m, int frame_offset) {
  std::vector<SubmapQualityRecord> out(m.submaps().size());
  const Eigen::Isometry3d T_out_world = m.output_from_world();
  tbb::parallel_for(size_t{0}, out.size(), [&](size_t i) {
    const Submap& s = m.submaps()[i];
    out[i].id = s.id;
    out[i].first_frame = s.keyframes.front() + frame_offset;
    out[i].last_frame = s.keyframes.back() + frame_offset;
    out[i].baseline = s.keyframe_noise ? NoiseBaseline::keyframes : NoiseBaseline::consecutive_submaps;
    out[i].keyframe_noise = s.keyframe_noise.value_or(0.0f);
    out[i].noise = out[i].keyframe_noise;
    out[i].position = (T_out_world * m.submap_pose(s.id)).translation();
    out[i].entropy = mean_map_entropy(evenly_subsampled(*s.cloud, kEntropyPoints), kEntropyRadius).mean;
  });
  return out;
}

std::vector<StampAnomaly> stamp_anomalies(const std::vector<double>& stamps, double factor, int frame_offset) {
  std::vector<double> intervals;
  for (size_t i = 1; i < stamps.size(); ++i) intervals.push_back(stamps[i] - stamps[i - 1]);
  const double typical = median(intervals);
  std::vector<StampAnomaly> out;
  for (size_t i = 0; i < intervals.size(); ++i)
    if (intervals[i] <= 0.0 || intervals[i] > factor * typical)
      out.push_back({static_cast<int>(i + 1) + frame_offset, intervals[i]});
  return out;
}

// Runs of frames with `flag`, gaps of up to kStretchGap frames joined, at least kMinStretch long:
// first and last positions in `frames`.
template <class Flag>
std::vector<std::pair<int, int>> stretches(const std::vector<FrameQualityRecord>& frames, Flag flag, int min_length) {
  std::vector<std::pair<int, int>> out;
  for (int k = 0; k < static_cast<int>(frames.size()); ++k) {
    if (!flag(frames[k])) continue;
    if (!out.empty() && k - out.back().second <= kStretchGap + 1) out.back().second = k;
    else out.emplace_back(k, k);
  }
  std::erase_if(out, [&](const auto& s) { return s.second - s.first + 1 < min_length; });
  return out;
}

// The weak axis most frames of a stretch share.
WeakAxis dominant_axis(const std::vector<FrameQualityRecord>& frames, int first, int last) {
  int counts[4] = {0, 0, 0, 0};
  for (int i = first; i <= last; ++i)
    if (frames[i].degenerate) ++counts[static_cast<int>(frames[i].weak_axis)];
  return static_cast<WeakAxis>(std::max_element(counts, counts + 4) - counts);
}

void degeneracy_verdict(QualityReport& r) {
  for (const auto& [a, b] : stretches(
           r.frames, [](const auto& f) { return f.degenerate; }, kMinStretch)) {
    const double length = r.frames[b].travelled - r.frames[a].travelled;
    r.verdict.push_back(format("frames %d-%d: registration degenerate (weak %s) over %.0f m: the odometry may drift there",
                               r.frames[a].index, r.frames[b].index, to_string(dominant_axis(r.frames, a, b)), length));
  }
}

void failure_verdict(QualityReport& r) {
  for (const auto& [a, b] : stretches(
           r.frames, [](const auto& f) { return f.failed; }, 1))
    r.verdict.push_back(format("frames %d-%d: odometry failed (%s): placed by the prediction (the last motion, or the IMU)",
                               r.frames[a].index, r.frames[b].index, to_string(r.frames[a].figures.registration.failure)));
}

void consistency_verdict(QualityReport& r) {
  for (const auto& p : r.pairs) {
    if (!p.inconsistent) continue;
    const auto &s = r.submaps[p.source], &t = r.submaps[p.target];
    r.verdict.push_back(
        format("submaps %d and %d (frames %d-%d and %d-%d) disagree by %.3f m, %.1f deg (their noise: %.3f m): "
               "a revisit that did not close",
               t.id, s.id, t.first_frame, t.last_frame, s.first_frame, s.last_frame, p.shift, p.rotation_deg, p.noise));
  }
}

void other_verdict(QualityReport& r) {
  const auto accepted = std::count_if(r.loops.begin(), r.loops.end(), [](const LoopRecord& l) { return l.accepted; });
  if (!r.loops.empty())
    r.verdict.push_back(
        format("%zu explicit loop candidates verified, %ld accepted", r.loops.size(), static_cast<long>(accepted)));
  if (!r.stamp_anomalies.empty())
    r.verdict.push_back(
        format("%zu stamp anomalies (gaps over %.1fx the usual interval, or stamps not increasing), first at frame %d",
               r.stamp_anomalies.size(), r.thresholds.stamp_gap_factor, r.stamp_anomalies.front().frame));
}

Json frame_json(const FrameQualityRecord& f) {
  const RegistrationQuality& q = f.figures.registration;
  Json j = Json::object();
  j["frame"] = f.index;
  j["registered"] = q.registered;
  j["translation_information"] =
      Json::Array{q.translation_information[0], q.translation_information[1], q.translation_information[2]};
  j["conditioning"] = q.conditioning();
  j["weak_direction"] = Json::Array{q.weak_direction.x(), q.weak_direction.y(), q.weak_direction.z()};
  j["weak_axis"] = to_string(f.weak_axis);
  j["inlier_fraction"] = q.inlier_fraction;
  j["deskew_shift"] = f.figures.deskew_shift;
  j["degenerate"] = f.degenerate;
  j["odometry_failed"] = f.failed;
  if (f.failed) j["failure_cause"] = to_string(q.failure);
  return j;
}

Json submap_json(const SubmapQualityRecord& s) {
  Json j = Json::object();
  j["id"] = s.id;
  j["first_frame"] = s.first_frame;
  j["last_frame"] = s.last_frame;
  j["position"] = Json::Array{s.position.x(), s.position.y(), s.position.z()};
  j["entropy"] = s.entropy;
  if (s.baseline == NoiseBaseline::keyframes) j["keyframe_noise"] = s.keyframe_noise;
  j["noise"] = s.noise;
  j["noise_baseline"] = to_string(s.baseline);
  j["worst_shift"] = s.worst_shift;
  j["worst_ratio"] = s.worst_ratio;
  j["inconsistent"] = s.inconsistent;
  return j;
}

Json pair_json(const SubmapPairRecord& p) {
  Json j = Json::object();
  j["source"] = p.source;
  j["target"] = p.target;
  j["shift"] = p.shift;
  j["rotation_deg"] = p.rotation_deg;
  j["inlier_fraction"] = p.inlier_fraction;
  j["coarse"] = p.coarse;
  j["noise"] = p.noise;
  j["limit"] = p.limit;
  j["inconsistent"] = p.inconsistent;
  return j;
}

Json thresholds_json(const QualityConfig& t) {
  Json j = Json::object();
  j["degenerate_conditioning"] = t.degenerate_conditioning;
  j["inconsistent_factor"] = t.inconsistent_factor;
  j["min_shift"] = t.min_shift;
  j["pair_radius"] = t.pair_radius;
  j["min_pair_inliers"] = t.min_pair_inliers;
  j["coarse_resolution"] = t.coarse_resolution;
  j["stamp_gap_factor"] = t.stamp_gap_factor;
  return j;
}

template <class T, class F>
Json array_json(const std::vector<T>& v, F f) {
  Json a = Json::array();
  for (const T& x : v) a.push_back(f(x));
  return a;
}

}  // namespace

const char* to_string(WeakAxis a) {
  switch (a) {
    case WeakAxis::none: return "none";
    case WeakAxis::along_travel: return "along the direction of travel";
    case WeakAxis::across_travel: return "across the direction of travel";
    case WeakAxis::vertical: return "vertically";
  }
  return "";
}

const char* to_string(NoiseBaseline b) {
  switch (b) {
    case NoiseBaseline::keyframes: return "keyframes";
    case NoiseBaseline::consecutive_submaps: return "consecutive submaps";
  }
  return "";
}

QualityReport assess_quality(const MappingPipeline& pipeline, const QualityConfig& thresholds, int frame_offset) {
  QualityReport r;
  r.thresholds = thresholds;
  r.frame_offset = frame_offset;
  r.frames = assess_frames(pipeline, thresholds, frame_offset);
  r.submaps = assess_submaps(pipeline.mapper(), frame_offset);
  r.pairs = compare_pairs(pipeline.mapper(), thresholds);
  flag_pairs(r, pipeline.mapper());
  r.loops = pipeline.loops();
  r.stamp_anomalies = stamp_anomalies(pipeline.stamps(), thresholds.stamp_gap_factor, frame_offset);
  degeneracy_verdict(r);
  failure_verdict(r);
  consistency_verdict(r);
  if (r.verdict.empty()) r.verdict.push_back("no degenerate stretch, odometry failure or disagreeing submaps found");
  other_verdict(r);
  return r;
}

Json quality_json(const QualityReport& r) {
  Json j = Json::object();
  j["verdict"] = array_json(r.verdict, [](const std::string& s) { return Json(s); });
  j["thresholds"] = thresholds_json(r.thresholds);
  j["consecutive_submap_shift"] = r.consecutive_shift;
  j["frames"] = array_json(r.frames, frame_json);
  j["submaps"] = array_json(r.submaps, submap_json);
  j["submap_pairs"] = array_json(r.pairs, pair_json);
  j["loops"] = array_json(r.loops, loop_json);
  j["stamp_anomalies"] = array_json(r.stamp_anomalies, [](const StampAnomaly& a) {
    Json s = Json::object();
    s["frame"] = a.frame;
    s["interval"] = a.interval;
    return s;
  });
  return j;
}

}  // namespace gcmap
