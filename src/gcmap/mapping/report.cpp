#include "gcmap/mapping/report.hpp"

namespace gcmap {

namespace {

Json timing_json(const TimingStats& t) {
  Json j = Json::object();
  j["mean_ms"] = t.mean();
  j["std_ms"] = t.stddev();
  j["max_ms"] = t.max();
  j["count"] = t.samples_ms.size();
  return j;
}

Json submaps_json(const Mapper& mapper, int frame_offset) {
  Json submaps = Json::array();
  const Eigen::Isometry3d T_out_world = mapper.output_from_world();
  for (const Submap& s : mapper.submaps()) {
    Json j = Json::object();
    j["id"] = s.id;
    j["pose"] = pose_json(T_out_world * mapper.submap_pose(s.id));
    j["first_frame"] = s.keyframes.front() + frame_offset;
    j["last_frame"] = s.keyframes.back() + frame_offset;
    j["keyframes"] = s.keyframes.size();
    j["points"] = s.cloud->size();
    submaps.push_back(j);
  }
  return submaps;
}

}  // namespace

Json loop_json(const LoopRecord& l) {
  Json j = Json::object();
  j["source"] = l.source;
  j["target"] = l.target;
  j["descriptor_distance"] = l.descriptor_distance;
  j["inlier_fraction"] = l.inlier_fraction;
  j["inlier_rmse"] = l.inlier_rmse;
  j["conditioning"] = l.conditioning;
  j["accepted"] = l.accepted;
  return j;
}

Json graph_json(const MappingPipeline& pipeline, int frame_offset) {
  const Mapper& mapper = pipeline.mapper();
  Json graph = Json::object();
  graph["submaps"] = submaps_json(mapper, frame_offset);
  Json factors = Json::array();
  const std::vector<FactorEvaluation> evaluation = mapper.evaluate_factors();
  for (size_t f = 0; f < mapper.factors().size(); ++f) {
    const GlobalFactor& fi = mapper.factors()[f];
    Json j = Json::object();
    j["type"] = to_string(fi.kind);
    j["source"] = fi.source;
    j["target"] = fi.target;
    j["overlap"] = fi.overlap;
    j["final_error"] = evaluation[f].error;
    if (fi.kind != FactorKind::matching_cost) j["final_weight"] = evaluation[f].weight;
    j["explicit_loop"] = fi.kind == FactorKind::loop;
    factors.push_back(j);
  }
  graph["factors"] = factors;
  Json loops = Json::array();  // every verified candidate, accepted or not
  for (const LoopRecord& l : mapper.loops()) loops.push_back(loop_json(l));
  graph["loop_candidates"] = loops;
  return graph;
}

std::string map_frame_description(const Mapper& mapper) {
  if (mapper.georeferenced()) return "local ENU at the first GNSS fix (x east, y north, z up)";
  if (mapper.levelled()) return "the first frame's position and heading, z up (levelled by the IMU's gravity)";
  return "the first frame";
}

Json rotation_smoothing_json(const RotationSmoothing& s) {
  Json j = Json::object();
  j["applied"] = s.applied;
  j["windows"] = s.windows;                  // runs of frames the trajectory was measured against the gyro over
  j["frame_noise_deg"] = s.frame_noise_deg;  // per frame and axis, before smoothing
  j["gyro_noise_deg"] = s.gyro_noise_deg;    // between consecutive frames, per axis
  return j;
}

Json stats_json(const MappingPipeline& pipeline) {
  const PipelineStats ps = pipeline.stats();
  const MapperStats& ms = ps.mapper;
  Json stats = Json::object();
  stats["frames"] = ps.frames;
  stats["unusable_scans"] = ps.unusable;
  stats["odometry_failures"] = ps.odometry_failures;
  stats["map_frame"] = map_frame_description(pipeline.mapper());
  if (ps.imu_samples > 0) {
    Json imu = Json::object(), bias = Json::array();
    for (int i = 0; i < 3; ++i) bias.push_back(ps.gyro_bias[i]);
    imu["samples"] = ps.imu_samples;
    imu["gyro_deskewed_sweeps"] = ps.gyro_deskewed;
    imu["gyro_bias_rad_s"] = bias;  // LiDAR frame, the estimate at the end
    if (ps.gyro_rejected_at) imu["gyro_rejected_at_frame"] = *ps.gyro_rejected_at;
    imu["inertial_predicted_sweeps"] = ps.inertial_predicted;
    // Where the registered rates scatter over twice the gyro's noise (a sensor in hand).
    imu["inertial_deskewed_sweeps"] = ps.inertial_deskewed;
    imu["submap_gyro_factors"] = ms.local.gyro_factors;  // between consecutive keyframes of a submap
    if (ps.inertial_bias) {
      Json gyro = Json::array(), accel = Json::array();
      for (int i = 0; i < 3; ++i) gyro.push_back(ps.inertial_bias->gyro[i]), accel.push_back(ps.inertial_bias->accel[i]);
      imu["inertial_gyro_bias_rad_s"] = gyro;  // IMU frame, the LiDAR-inertial state's at the end
      imu["inertial_accel_bias_m_s2"] = accel;
    }
    if (ps.inertial_gravity_turn_deg) imu["inertial_gravity_turned_deg"] = *ps.inertial_gravity_turn_deg;
    if (ps.imu_clock) {
      Json clock = Json::object();
      clock["best_shift_s"] = ps.imu_clock->best_shift;  // to add to imu.time_offset
      clock["rate_rms_at_configured_offset_rad_s"] = ps.imu_clock->rms_at_zero;
      clock["rate_rms_at_best_shift_rad_s"] = ps.imu_clock->rms_at_best;
      clock["registered_rate_rms_rad_s"] = ps.imu_clock->rms_rate;
      clock["windows"] = ps.imu_clock->windows;
      // What explains that rms as white gyro noise (the registration's error included).
      clock["gyro_noise_density_rad_s_sqrt_hz"] = ps.imu_clock->noise_density;
      imu["clock_check"] = clock;
    }
    imu["deskew_gyro_noise_rad_s_sqrt_hz"] = ps.deskew_gyro_noise;  // imu.gyro_noise, or the measured density under 0.8 of it
    const GravityStats& g = ps.gravity;
    Json gravity = Json::object(), ab = Json::array();
    for (int k = 0; k < 3; ++k) ab.push_back(g.accel_bias[k]);
    gravity["levelled"] = g.levelled;  // the map's z is gravity's
    gravity["windows"] = g.windows;
    gravity["downweighted"] = g.downweighted;
    gravity["accel_bias_m_s2"] = ab;           // IMU frame, the estimate at the end
    gravity["rms_tilt_deg"] = g.rms_tilt_deg;  // of the windows' up against the map's z
    imu["gravity"] = gravity;
    imu["rotation_smoothing"] = rotation_smoothing_json(pipeline.mapper().rotation_smoothing());
    stats["imu"] = imu;
  }
  stats["seconds"] = ps.seconds;
  stats["frames_per_second"] = ps.seconds > 0 ? ps.frames / ps.seconds : 0.0;
  stats["device"] = pipeline.backend().name();
  Json timing = Json::object();
  timing["preprocess"] = timing_json(ps.preprocess);
  timing["odometry"] = timing_json(ps.odometry);
  timing["local_factor_creation"] = timing_json(ms.local.factors);
  timing["local_optimization"] = timing_json(ms.local.optimization);
  timing["global_factor_creation"] = timing_json(ms.global.factors);
  timing["global_optimization"] = timing_json(ms.global.optimization);
  timing["loop_detection"] = timing_json(ms.loop.detection);
  timing["loop_verification"] = timing_json(ms.loop.verification);
  stats["timing"] = timing;
  Json per = Json::array();
  for (const auto& p : ms.global.per_submap) {
    Json j = Json::object();
    j["submaps"] = p.num_submaps;
    j["factors"] = p.num_factors;
    j["global_optimization_ms"] = p.global_optimization_ms;
    j["global_iterations"] = p.global_iterations;
    j["linearize_ms"] = p.linearize_ms;
    j["assemble_ms"] = p.assemble_ms;
    j["solve_ms"] = p.solve_ms;
    j["factors_linearized"] = p.linearized;
    per.push_back(j);
  }
  stats["per_submap"] = per;
  stats["final_optimization_ms"] = ms.global.final_optimization_ms;
  stats["final_iterations"] = ms.global.final_iterations;
  stats["factor_linearizations"] = ms.global.factor_linearizations;
  stats["factor_reuses"] = ms.global.factor_reuses;
  stats["factor_deferrals"] = ms.global.factor_deferrals;
  stats["linear_solver"] = linear_solver_name(ms.global.linear_solver);
  return stats;
}

}  // namespace gcmap
