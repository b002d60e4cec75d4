#include "gcmap/sim/synthetic.hpp"

#include <cmath>
#include <random>

namespace gcmap {

PointCloud make_structured_scene(size_t n, uint64_t seed, double extent) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const double e = extent;
  PointCloud cloud;
  cloud.points.reserve(n);
  for (size_t i = 0; i < n; ++i) {
    const int kind = static_cast<int>(i % 9);
    Eigen::Vector3d p;
    switch (kind) {
      case 0:
      case 1:  // ground with a gentle slope
        p = {e * u(rng), e * u(rng), 0.0};
        p.z() = 0.02 * p.x() - 2.0;
        break;
      case 2:  // wall x = e
        p = {e, e * u(rng), -2.0 + 3.0 * (u(rng) + 1.0)};
        break;
      case 3:  // wall y = -e
        p = {e * u(rng), -e, -2.0 + 2.0 * (u(rng) + 1.0)};
        break;
      case 4: {  // oblique wall
        const double s = u(rng);
        p = {-0.5 * e + 0.3 * e * s, 0.5 * e + 0.4 * e * s, -2.0 + 2.5 * (u(rng) + 1.0)};
        break;
      }
      case 5: {  // box faces
        const double a = u(rng), b = u(rng);
        const int face = static_cast<int>((u(rng) + 1.0) * 2.0) % 4;
        const Eigen::Vector3d c(0.3 * e, 0.3 * e, -1.0);
        if (face == 0) p = c + Eigen::Vector3d(2.0, 2.0 * a, b);
        else if (face == 1) p = c + Eigen::Vector3d(-2.0, 2.0 * a, b);
        else if (face == 2) p = c + Eigen::Vector3d(2.0 * a, 2.0, b);
        else p = c + Eigen::Vector3d(2.0 * a, 2.0 * b, 1.0);
        break;
      }
      case 6: {  // sphere
        Eigen::Vector3d d(u(rng), u(rng), u(rng));
        if (d.norm() < 1e-3) d = Eigen::Vector3d::UnitZ();
        p = Eigen::Vector3d(-0.4 * e, -0.4 * e, 0.0) + 1.5 * d.normalized();
        break;
      }
      default: {  // vertical cylinders (poles)
        const double ang = M_PI * u(rng);
        const double cx = kind == 7 ? 0.1 * e : -0.2 * e, cy = kind == 7 ? -0.3 * e : 0.1 * e;
        p = {cx + 0.4 * std::cos(ang), cy + 0.4 * std::sin(ang), -2.0 + 2.5 * (u(rng) + 1.0)};
        break;
      }
    }
    cloud.points.push_back(p.cast<float>());
  }
  return cloud;
}

PointCloud make_tunnel_scan(size_t n, uint64_t seed, double max_range) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::normal_distribution<double> noise(0.0, 0.01);
  PointCloud cloud;
  cloud.points.reserve(n);
  while (cloud.points.size() < n) {
    const double az = 2.0 * M_PI * u(rng), el = (u(rng) - 0.5) * M_PI / 3.0;
    const Eigen::Vector3d d(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el));
    // The nearest of the walls (y = +-5) and the floor or roof.
    double t = std::abs(d.y()) > 1e-9 ? 5.0 / std::abs(d.y()) : 1e9;
    if (d.z() < -1e-9) t = std::min(t, -2.0 / d.z());
    if (d.z() > 1e-9) t = std::min(t, 4.0 / d.z());
    if (t > max_range) continue;
    cloud.points.push_back(((t + noise(rng)) * d).cast<float>());
  }
  return cloud;
}

}  // namespace gcmap
