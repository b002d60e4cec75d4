#include <algorithm>
#include <cmath>

#include "gcmap/sim/rng.hpp"
#include "gcmap/sim/scenario.hpp"

namespace gcmap::sim {

namespace {
constexpr double kFramePeriod = 0.1;
constexpr double kAccel = 1.5, kDecel = 2.5;  // m/s^2
constexpr int kChord = 20;                    // samples (1 m) for headings and curvature
}  // namespace

Drive::Drive(const Scenario& s, const World& world, uint64_t seed)
    : world_(world), sensor_height_(s.sensor_height), handheld_(s.handheld), seed_(seed) {
  std::vector<size_t> corner_starts;
  lane_ = shifted_right(route_centerline(s, &corner_starts), s.lane_offset);
  arc_.assign(lane_.size(), 0.0);
  for (size_t i = 1; i < lane_.size(); ++i) arc_[i] = arc_[i - 1] + (lane_[i] - lane_[i - 1]).norm();
  length_ = arc_.back();
  even_ = !s.realistic;
  if (even_) {
    num_frames_ = static_cast<size_t>(s.frames);
    return;
  }
  speed_profile(s, corner_starts, seed);
  const size_t all = static_cast<size_t>(knot_t_.back() / kFramePeriod) + 1;
  num_frames_ = s.frames > 0 ? std::min<size_t>(all, static_cast<size_t>(s.frames)) : all;
}

// Speed limits from the cruise speed and the curvature, zero at stops; then acceleration limits
// forwards and backwards; then time by integration (stops add their dwell).
void Drive::speed_profile(const Scenario& s, const std::vector<size_t>& corner_starts, uint64_t seed) {
  const size_t n = lane_.size();
  std::vector<double> v(n), dwell(n, 0.0);
  for (size_t i = 0; i < n; ++i) {
    const size_t a = i >= kChord ? i - kChord : 0, b = std::min(i + kChord, n - 1);
    const Eigen::Vector2f t0 = (lane_[i] - lane_[a]).normalized(), t1 = (lane_[b] - lane_[i]).normalized();
    const double turn = (a == i || b == i) ? 0.0 : std::acos(std::clamp<double>(t0.dot(t1), -1.0, 1.0));
    const double kappa = turn / std::max(arc_[b] - arc_[a], 1e-3) * 2.0;
    Rng r(hash_key(seed, 0x5BD, static_cast<uint64_t>(arc_[i] / 150.0)));
    v[i] = std::min<double>(r.uniform(s.cruise_min, s.cruise_max), std::sqrt(s.lateral_accel / std::max(kappa, 1e-9)));
  }
  if (s.rest_at_ends) v.front() = 0.0, v.back() = 0.0;
  for (size_t k = 1; s.stop_every > 0 && k + 1 < corner_starts.size(); ++k) {
    if (k % s.stop_every != 0) continue;
    // Stop line 5 m before the intersection.
    const size_t i = corner_starts[k] > 100 ? corner_starts[k] - 100 : 0;
    v[i] = 0.0;
    dwell[i] = Rng(hash_key(seed, 0x570, k)).uniform(2.f, 6.f);
  }
  for (size_t i = 1; i < n; ++i) v[i] = std::min(v[i], std::sqrt(v[i - 1] * v[i - 1] + 2 * kAccel * (arc_[i] - arc_[i - 1])));
  for (size_t i = n - 1; i-- > 0;) v[i] = std::min(v[i], std::sqrt(v[i + 1] * v[i + 1] + 2 * kDecel * (arc_[i + 1] - arc_[i])));
  double t = 0.0;
  for (size_t i = 0; i < n; ++i) {
    if (i > 0) t += 2.0 * (arc_[i] - arc_[i - 1]) / std::max(v[i] + v[i - 1], 1e-3);
    knot_t_.push_back(t), knot_s_.push_back(arc_[i]), knot_v_.push_back(v[i]);
    if (dwell[i] > 0) t += dwell[i], knot_t_.push_back(t), knot_s_.push_back(arc_[i]), knot_v_.push_back(v[i]);
  }
}

double Drive::arclength(double frame) const {
  if (even_) return length_ * frame / (num_frames_ - 1);
  const double t = frame * kFramePeriod;
  if (t > knot_t_.back() && knot_t_.size() > 1) {  // at the speed of the last interval
    const size_t j = knot_t_.size() - 1;
    const double dt = knot_t_[j] - knot_t_[j - 1];
    return knot_s_[j] + (dt > 0 ? (t - knot_t_[j]) * (knot_s_[j] - knot_s_[j - 1]) / dt : 0.0);
  }
  const size_t j =
      std::clamp<size_t>(std::upper_bound(knot_t_.begin(), knot_t_.end(), t) - knot_t_.begin(), 1, knot_t_.size() - 1);
  const double dt = knot_t_[j] - knot_t_[j - 1];
  if (dt <= 0) return knot_s_[j];
  if (knot_v_[j - 1] + knot_v_[j] < 1e-3) return knot_s_[j - 1] + (t - knot_t_[j - 1]) / dt * (knot_s_[j] - knot_s_[j - 1]);
  // Within a knot interval the speed changes linearly from one knot's to the next's; the interval's
  // length makes their mean cover its arc exactly.
  const double u = std::clamp(t - knot_t_[j - 1], 0.0, dt), a = (knot_v_[j] - knot_v_[j - 1]) / dt;
  return std::min(knot_s_[j - 1] + knot_v_[j - 1] * u + 0.5 * a * u * u, knot_s_[j]);
}

Eigen::Isometry3d Drive::pose(double frame) const {
  const double s = arclength(frame);
  const size_t seg = std::min<size_t>(std::lower_bound(arc_.begin() + 1, arc_.end(), s) - arc_.begin(), lane_.size() - 1) - 1;
  // Beyond the route's end (the last sweep's later firings) the vehicle goes on straight: clamped,
  // it would stop dead within that sweep.
  const double f = std::max((s - arc_[seg]) / std::max(arc_[seg + 1] - arc_[seg], 1e-9), 0.0);
  const Eigen::Vector2f p = lane_[seg] + static_cast<float>(f) * (lane_[seg + 1] - lane_[seg]);
  // Heading from a short look-ahead/behind chord smooths the polyline's kinks; interpolated
  // between the chords of neighbouring vertices so that it turns continuously, not in steps.
  const auto chord = [&](size_t i) {
    const size_t a = i >= kChord ? i - kChord : 0, b = std::min<size_t>(i + kChord, lane_.size() - 1);
    return Eigen::Vector2d((lane_[b] - lane_[a]).cast<double>().normalized());
  };
  const Eigen::Vector2d t = ((1.0 - f) * chord(seg) + f * chord(seg + 1)).normalized();
  // The vehicle follows the terrain: z along the ground normal, x along the heading.
  const Eigen::Vector2f g = world_.ground_gradient(p.x(), p.y());
  const Eigen::Vector3d z = Eigen::Vector3d(-g.x(), -g.y(), 1.0).normalized();
  Eigen::Vector3d x(t.x(), t.y(), 0.0);
  x = (x - x.dot(z) * z).normalized();
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear().col(0) = x;
  T.linear().col(1) = z.cross(x);
  T.linear().col(2) = z;
  T.translation() = Eigen::Vector3d(p.x(), p.y(), world_.ground_height(p.x(), p.y()) + sensor_height_);
  return handheld_ ? T * gait(frame * kFramePeriod) : T;
}

namespace {
constexpr double kStepHz = 1.8;      // steps per second
constexpr double kGlanceEvery = 7.0;  // s between glances
constexpr double kGlance = 1.0;       // s a glance takes, there and back
constexpr double kGlanceDeg = 60.0;   // how far aside: a raised cosine peaks at pi * 60 / 1.0 = 188 deg/s
}  // namespace

Eigen::Isometry3d Drive::gait(double t) const {
  // Walking speed over half a second: standing still, the hand barely moves.
  const double v = (arclength((t + 0.25) / kFramePeriod) - arclength((t - 0.25) / kFramePeriod)) / 0.5;
  const double walk = std::clamp(v / 1.2, 0.0, 1.0), step = 2.0 * M_PI * kStepHz * t;
  // A glance in each kGlanceEvery window, to a side drawn from the seed.
  const double k = std::floor(t / kGlanceEvery), u = (t - k * kGlanceEvery - 0.5 * kGlanceEvery) / kGlance;
  const double side = Rng(hash_key(seed_, 0x61A, static_cast<uint64_t>(k))).uniform() < 0.5 ? -1.0 : 1.0;
  const double glance = (u >= 0.0 && u <= 1.0) ? side * kGlanceDeg * 0.5 * (1.0 - std::cos(2.0 * M_PI * u)) : 0.0;
  constexpr double kDeg = M_PI / 180.0;
  Eigen::Isometry3d G = Eigen::Isometry3d::Identity();
  G.translation() << 0.0, walk * 0.02 * std::sin(0.5 * step), walk * 0.025 * std::cos(step);
  G.linear() = (Eigen::AngleAxisd((glance + walk * 3.0 * std::sin(0.5 * step + 0.3)) * kDeg, Eigen::Vector3d::UnitZ()) *
                Eigen::AngleAxisd(walk * 1.5 * std::sin(step + 0.5) * kDeg, Eigen::Vector3d::UnitY()) *
                Eigen::AngleAxisd(walk * 2.0 * std::sin(0.5 * step) * kDeg, Eigen::Vector3d::UnitX()))
                   .toRotationMatrix();
  return G;
}

}  // namespace gcmap::sim
