#include "gcmap/core/error.hpp"
#include "gcmap/eval/map_entropy.hpp"
#include "gcmap/eval/trajectory_metrics.hpp"
#include "gcmap/io/trajectory_io.hpp"
#include "test_util.hpp"

namespace gcmap {
namespace {

Poses straight_line(int n) {
  Poses p;
  for (int i = 0; i < n; ++i) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.translation().x() = i;  // 1 m per frame
    p.push_back(T);
  }
  return p;
}

TEST(KittiError, IdenticalTrajectoriesGiveZero) {
  const Poses gt = straight_line(1000);
  const KittiError k = kitti_relative_error(gt, gt);
  EXPECT_GT(k.num_segments, 0u);
  EXPECT_EQ(k.translation_percent, 0.0);
  EXPECT_EQ(k.rotation_deg_per_100m, 0.0);
  EXPECT_EQ(absolute_trajectory_error(gt, gt).rmse, 0.0);
}

TEST(KittiError, InjectedScaleDriftMatchesDevkitByHand) {
  // est moves 1.01 m per 1 m. The devkit ends a segment of length L at the first frame strictly
  // beyond L m, i.e. L + 1 frames later here, and divides by L: error = 0.01 (L + 1) / L.
  const Poses gt = straight_line(1001);
  Poses est = gt;
  for (auto& T : est) T.translation() *= 1.01;
  const KittiError k = kitti_relative_error(gt, est);
  double sum = 0.0;
  size_t count = 0;
  for (const auto& s : k.per_length) {
    const double L = s.length;
    // first frames 0, 10, ..., with first + L + 1 <= 1000.
    const size_t expected_count = static_cast<size_t>((1000 - (L + 1)) / 10) + 1;
    EXPECT_EQ(s.count, expected_count) << L;
    EXPECT_NEAR(s.translation_percent, 1.0 * (L + 1) / L, 1e-9) << L;
    EXPECT_NEAR(s.rotation_deg_per_100m, 0.0, 1e-9);
    sum += s.count * 0.01 * (L + 1) / L;
    count += s.count;
  }
  EXPECT_EQ(k.num_segments, count);
  EXPECT_NEAR(k.translation_percent, 100.0 * sum / count, 1e-9);
}

TEST(KittiError, InjectedHeadingDriftMatchesDevkitByHand) {
  // Orientation drifts by alpha per frame: over a segment of L + 1 frames the rotation error is
  // alpha (L + 1), reported per metre of L.
  const double alpha = 1e-4;
  const Poses gt = straight_line(1001);
  Poses est = gt;
  for (size_t i = 0; i < est.size(); ++i) est[i].linear() = so3_exp(Eigen::Vector3d(0, 0, alpha * i));
  const KittiError k = kitti_relative_error(gt, est);
  for (const auto& s : k.per_length)
    EXPECT_NEAR(s.rotation_deg_per_100m, alpha * (s.length + 1) / s.length * 180.0 / M_PI * 100.0, 1e-6) << s.length;
}

TEST(Ate, UmeyamaRemovesARigidOffset) {
  std::mt19937_64 rng(5);
  Poses gt;
  for (int i = 0; i < 50; ++i) gt.push_back(test::random_pose(rng, 1.0, 30.0));
  const Eigen::Isometry3d W = test::random_pose(rng, 2.0, 100.0);
  Poses est;
  for (const auto& T : gt) est.push_back(W * T);
  const AbsoluteError a = absolute_trajectory_error(gt, est);
  EXPECT_LT(a.rmse, 1e-9);
  EXPECT_LT(test::translation_error(a.T_gt_est, W.inverse()), 1e-9);
  EXPECT_THROW(absolute_trajectory_error(gt, Poses(gt.begin(), gt.end() - 1)), Error);
}

TEST(KittiError, RealGroundTruthWithKnownPerturbation) {
  GCMAP_REQUIRE_SHARED_DATA("kitti00_gt");
  const Poses gt = read_trajectory(test::shared_data() + "/kitti00_gt/00.txt").poses;
  // A rigid change of world frame changes nothing.
  const Eigen::Isometry3d W = se3_exp((Vector6d() << 0.1, -0.2, 0.3, 10, 20, -5).finished());
  Poses moved;
  for (const auto& T : gt) moved.push_back(W * T);
  const KittiError same = kitti_relative_error(gt, moved);
  EXPECT_LT(same.translation_percent, 1e-6);
  EXPECT_LT(same.rotation_deg_per_100m, 1e-4);
  EXPECT_LT(absolute_trajectory_error(gt, moved).rmse, 1e-6);
  // One frame displaced by 1 m: frame-to-frame error peaks at exactly 1 m.
  Poses bumped = gt;
  bumped[2000].translation() += Eigen::Vector3d(1.0, 0, 0);
  const RelativePoseError r = relative_pose_error(gt, bumped);
  EXPECT_NEAR(r.translation_max, 1.0, 1e-6);
  EXPECT_GT(kitti_relative_error(gt, bumped).translation_percent, 0.0);
}

PointCloud noisy_plane(double sigma, uint64_t seed, double offset = 0.0) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<float> u(-3.f, 3.f);
  std::normal_distribution<float> n(0.f, static_cast<float>(sigma));
  PointCloud c;
  for (int i = 0; i < 40000; ++i) c.points.emplace_back(u(rng), u(rng), static_cast<float>(offset) + n(rng));
  return c;
}

TEST(MapEntropy, ThinnerSurfacesAndAlignedCopiesScoreLower) {
  const MapEntropy thin = mean_map_entropy(noisy_plane(0.005, 1));
  const MapEntropy thick = mean_map_entropy(noisy_plane(0.03, 1));
  EXPECT_GT(thin.num_points, 30000u);
  EXPECT_LT(thin.mean, thick.mean);
  PointCloud aligned = noisy_plane(0.005, 1), misaligned = aligned;
  const PointCloud copy = noisy_plane(0.005, 2), shifted = noisy_plane(0.005, 2, 0.1);
  aligned.points.insert(aligned.points.end(), copy.points.begin(), copy.points.end());
  misaligned.points.insert(misaligned.points.end(), shifted.points.begin(), shifted.points.end());
  EXPECT_LT(mean_map_entropy(aligned).mean + 0.5, mean_map_entropy(misaligned).mean);
  EXPECT_THROW(mean_map_entropy(aligned, -1.0), Error);
}

// Brute-force reference: every pair, in double.
MapEntropy brute_force_entropy(const PointCloud& map, double radius, int min_neighbors) {
  double sum = 0.0;
  size_t n_used = 0;
  for (const auto& q : map.points) {
    std::vector<Eigen::Vector3d> nb;
    for (const auto& p : map.points) {
      if ((p - q).squaredNorm() <= radius * radius) nb.push_back((p - q).cast<double>());
    }
    if (nb.size() < static_cast<size_t>(min_neighbors)) continue;
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (const auto& p : nb) mean += p;
    mean /= nb.size();
    Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
    for (const auto& p : nb) cov += (p - mean) * (p - mean).transpose();
    cov /= nb.size();
    sum += 0.5 * std::log((2.0 * M_PI * M_E * cov).determinant());
    ++n_used;
  }
  MapEntropy out;
  out.num_points = n_used;
  out.mean = n_used ? sum / n_used : 0.0;
  return out;
}

TEST(MapEntropy, CellGridSearchMatchesBruteForce) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<float> u(-1.f, 1.f);
  std::normal_distribution<float> n(0.f, 0.05f);
  PointCloud map;
  for (int i = 0; i < 3000; ++i) map.points.emplace_back(u(rng), u(rng), 0.3f * u(rng) * u(rng) + n(rng));
  const MapEntropy reference = brute_force_entropy(map, 0.3, 15);
  const MapEntropy fast = mean_map_entropy(map, 0.3, 15);
  EXPECT_EQ(fast.num_points, reference.num_points);
  EXPECT_NEAR(fast.mean, reference.mean, 1e-4);
  // A far outlier stretches the extent beyond what half-radius cells can pack: cells grow, the
  // query must stay exact.
  map.points.emplace_back(4.0e5f, 0.f, 0.f);
  const MapEntropy stretched = mean_map_entropy(map, 0.3, 15);
  EXPECT_EQ(stretched.num_points, reference.num_points);
  EXPECT_NEAR(stretched.mean, reference.mean, 1e-4);
  map.points.emplace_back(std::nanf(""), 0.f, 0.f);
  EXPECT_THROW(mean_map_entropy(map), Error);
}

}  // namespace
}  // namespace gcmap
