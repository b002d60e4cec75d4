// The simulated GNSS receiver against its own stated model.
#include <cmath>

#include "gcmap/io/gnss_io.hpp"
#include "gcmap/sim/gnss.hpp"
#include "test_util.hpp"

namespace gcmap {
namespace {

const Geodetic kOrigin{48.137154, 11.576124, 520.0};

// The receiver's errors against the truth match the sigmas it states and writes.
TEST(GnssSimulation, ErrorsMatchTheStatedQuality) {
  sim::SimulationConfig c;
  c.scenario = "small";
  const sim::Simulator simulator(c);
  for (const sim::GnssQuality q : {sim::GnssQuality::rtk, sim::GnssQuality::float_solution}) {
    sim::GnssSimConfig g;
    g.quality = q;
    g.origin = kOrigin;
    g.rate = 50.0;
    const sim::SimulatedGnss out = sim::simulate_gnss(simulator, g, 3);
    ASSERT_GT(out.fixes.size(), 500u);
    Eigen::Vector3d sq = Eigen::Vector3d::Zero();
    for (size_t k = 0; k < out.fixes.size(); ++k) {
      const Eigen::Vector3d e = enu_from_geodetic(kOrigin, out.fixes[k].position) - out.truth_enu[k];
      sq += e.cwiseProduct(e) / double(out.fixes.size());
    }
    const sim::GnssNoise n = sim::gnss_noise(q);
    // White RTK noise averages out over 750 fixes; the float error is correlated over 10 s of a
    // 15 s drive, so its sample spread is loose.
    const double tol = q == sim::GnssQuality::rtk ? 0.15 : 0.7;
    EXPECT_NEAR(std::sqrt(sq.x()), n.sigma_horizontal, tol * n.sigma_horizontal) << to_string(q);
    EXPECT_NEAR(std::sqrt(sq.z()), n.sigma_vertical, tol * n.sigma_vertical) << to_string(q);
    EXPECT_EQ(out.fixes.front().sigma_enu.x(), n.sigma_horizontal);
  }
  sim::GnssSimConfig g;
  g.outlier_fraction = 0.1;
  g.outage = std::make_pair(2.0, 5.0);
  const sim::SimulatedGnss out = sim::simulate_gnss(simulator, g, 3);
  EXPECT_NEAR(double(out.outliers) / out.fixes.size(), 0.1, 0.05);
  EXPECT_EQ(out.in_outage, 30u);
  for (const GnssFix& f : out.fixes) EXPECT_FALSE(f.stamp >= 2.0 && f.stamp < 5.0);
}

}  // namespace
}  // namespace gcmap
