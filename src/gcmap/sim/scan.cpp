// Simulator::scan: casting one sweep's rays with the sensor errors the realism asks for.
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <random>

#include "gcmap/sim/rng.hpp"
#include "gcmap/sim/simulator.hpp"

namespace gcmap::sim {

namespace {
constexpr float kPi = 3.14159265f;
constexpr float kSpuriousRate = 3e-4f;   // per ray
constexpr float kMixedPixelRate = 0.4f;  // per depth edge (range jump > 1 m between neighbours)

// A return too weak to detect: reflectivity, incidence and range as in a LiDAR equation.
bool weak_return(const Hit& hit, Rng& rng) {
  const float r = std::max(hit.range, 1.f);
  return hit.reflectivity * hit.cos_incidence * (900.f / (r * r)) < 0.004f * (0.5f + rng.uniform());
}
}  // namespace

struct Simulator::Rays {
  int groups = 0, per = 0;
  std::vector<Eigen::Vector3f> points;
  std::vector<float> intensity, range, time;
  std::vector<uint32_t> label;
  std::vector<char> valid;
  Rays(int g, int p) : groups(g), per(p) {
    const size_t n = static_cast<size_t>(g) * p;
    points.resize(n), intensity.resize(n), range.resize(n), time.resize(n), label.resize(n), valid.assign(n, 0);
  }
};

void Simulator::cast_group(size_t frame, int g, const std::vector<ActiveMover>& movers, Rays& out) const {
  // One generator per group and frame: deterministic for any thread count. The first keeps the
  // historical stream (dropout, noise); the realism draws from the second.
  std::mt19937 rng(static_cast<uint32_t>(drive_seed_ * 1000003u + frame * 7919u + g));
  std::normal_distribution<float> noise(0.f, static_cast<float>(config_.noise));
  std::uniform_real_distribution<float> u(0.f, 1.f);
  Rng extra(hash_key(drive_seed_, frame, static_cast<uint64_t>(g)));
  const float dt = realism_.motion_distortion ? sensor_.period * g / out.groups : 0.f;
  const Eigen::Isometry3d T = realism_.motion_distortion ? pose_at(frame, dt) : poses_[frame];
  const Eigen::Matrix3f R = T.linear().cast<float>();
  const Eigen::Vector3f o = T.translation().cast<float>();
  const double sweep_start = frame * static_cast<double>(sensor_.period);
  // Movers whose azimuth window holds this group (a fixed array: no allocation per group; more
  // than 64 movers in one direction within range do not occur in our scenes).
  std::array<uint32_t, 64> near;
  size_t num_near = 0;
  if (!movers.empty()) {
    const Eigen::Vector3f d0 = sensor_.direction(g, 0, sweep_start);
    const float az = std::atan2(d0.y(), d0.x());
    for (size_t m = 0; m < movers.size() && num_near < near.size(); ++m) {
      const float diff = std::abs(std::remainder(az - movers[m].azimuth, 2.f * kPi));
      if (diff <= movers[m].half_width) near[num_near++] = static_cast<uint32_t>(m);
    }
  }
  for (int b = 0; b < out.per; ++b) {
    const Eigen::Vector3f d_local = sensor_.direction(g, b, sweep_start);
    Hit hit;
    const float drop = u(rng);
    const float n = config_.noise > 0 ? noise(rng) : 0.f;
    // A miscalibrated beam points elsewhere than the direction the points are computed with.
    const Eigen::Vector3f d =
        R * (realism_.calibration ? sensor_.direction(g, b, sweep_start, calibration_.elevation_bias_rad[b]) : d_local);
    bool found = world_->raycast(o, d, sensor_.max_range, hit, RayContext{static_cast<float>(sweep_start + dt), extra.next()});
    uint32_t label = hit.label;
    for (size_t k = 0; k < num_near; ++k) {
      const ActiveMover& m = movers[near[k]];
      float r, cos_inc;
      if (hit_mover(m, o, d, dt, r, cos_inc) && r < (found ? hit.range : sensor_.max_range)) {
        hit = Hit{r, m.reflectivity, m.label, cos_inc};
        label = m.label | ((m.id + 1) << 16);
        found = true;
      }
    }
    const size_t i = static_cast<size_t>(g) * out.per + b;
    float range = 0.f;
    if (realism_.spurious && extra.uniform() < kSpuriousRate) {
      range = extra.uniform(sensor_.min_range, 0.5f * sensor_.max_range);
      hit.reflectivity = extra.uniform(0.f, 0.3f), label = kOutlier;
    } else {
      if (!found) continue;
      if (drop < sensor_.dropout) continue;
      if (realism_.dropouts && weak_return(hit, extra)) continue;
      range = hit.range + (realism_.range_noise ? n * (0.5f + hit.range / 40.f) : n);
      if (realism_.calibration) range += calibration_.range_offset_m[b];
    }
    if (range < sensor_.min_range || range > sensor_.max_range) continue;
    out.points[i] = range * d_local;
    out.intensity[i] = std::clamp(hit.reflectivity * (1.f - range / 200.f), 0.f, 1.f);
    out.range[i] = range, out.time[i] = dt, out.label[i] = label, out.valid[i] = 1;
  }
}

// Where neighbouring returns of a beam jump in depth, the footprint straddles both surfaces and
// some returns land in between (sequential: a pure function of the scan).
void Simulator::mix_depth_edges(size_t frame, Rays& rays) const {
  for (int g = 0; g + 1 < rays.groups; ++g) {
    for (int b = 0; b < rays.per; ++b) {
      const size_t i = static_cast<size_t>(g) * rays.per + b, j = i + rays.per;
      if (!rays.valid[i] || !rays.valid[j] || std::abs(rays.range[i] - rays.range[j]) < 1.f) continue;
      const uint64_t key = hash_key(drive_seed_ ^ 0x313, frame, i);
      if (unit_float(key) >= kMixedPixelRate) continue;
      const size_t far = rays.range[i] > rays.range[j] ? i : j, close = far == i ? j : i;
      const float r = rays.range[close] + unit_float(mix64(key)) * (rays.range[far] - rays.range[close]);
      rays.points[far] *= r / rays.range[far];
      rays.range[far] = r, rays.label[far] = kOutlier;
    }
  }
}

PointCloud Simulator::scan(size_t frame, std::vector<uint32_t>* ray_ids) const {
  const Eigen::Isometry3d& T = poses_.at(frame);
  std::vector<ActiveMover> movers;
  if (realism_.moving_objects) movers = traffic_.active(T, frame * sensor_.period, sensor_.max_range, sensor_.period, *world_);
  Rays rays(sensor_.groups(), sensor_.rays_per_group());
  tbb::parallel_for(0, rays.groups, [&](int g) { cast_group(frame, g, movers, rays); });
  if (realism_.mixed_pixels) mix_depth_edges(frame, rays);
  PointCloud cloud;
  if (ray_ids) ray_ids->clear();
  for (size_t i = 0; i < rays.valid.size(); ++i) {
    if (!rays.valid[i]) continue;
    cloud.points.push_back(rays.points[i]);
    cloud.intensities.push_back(rays.intensity[i]);
    if (realism_.motion_distortion) cloud.times.push_back(rays.time[i]);
    if (realism_.labels) cloud.labels.push_back(rays.label[i]);
    if (ray_ids) ray_ids->push_back(static_cast<uint32_t>(i));
  }
  return cloud;
}

}  // namespace gcmap::sim
