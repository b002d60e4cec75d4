#include <Eigen/Eigenvalues>
#include <tbb/global_control.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <map>

#include "gcmap/core/error.hpp"
#include "gcmap/core/gaussian_voxel_map.hpp"
#include "gcmap/core/kdtree.hpp"
#include "gcmap/core/preprocess.hpp"
#include "gcmap/odometry/preprocess_scan.hpp"
#include "gcmap/sim/synthetic.hpp"
#include "test_util.hpp"

namespace gcmap {
namespace {

TEST(Downsample, AveragesEachVoxelAndIsDeterministic) {
  PointCloud c;
  c.points = {{0.01f, 0.01f, 0.01f}, {0.03f, 0.03f, 0.03f}, {0.5f, 0.5f, 0.5f}, {-0.01f, 0.0f, 0.0f}};
  c.intensities = {1.f, 3.f, 5.f, 7.f};
  c.labels = {10, 11, 12, 13};
  const PointCloud d = voxel_downsample(c, 0.1);
  ASSERT_EQ(d.size(), 3u);
  // Lexicographic voxel order: (-1,0,0), (0,0,0), (5,5,5).
  EXPECT_NEAR(d.points[0].x(), -0.01f, 1e-7);
  EXPECT_NEAR(d.points[1].x(), 0.02f, 1e-7);
  EXPECT_NEAR(d.intensities[1], 2.f, 1e-6);
  EXPECT_EQ(d.labels[1], 10u);
  EXPECT_NEAR(d.points[2].y(), 0.5f, 1e-7);

  const PointCloud big = make_structured_scene(50000, 7);
  const PointCloud a = voxel_downsample(big, 0.25);
  PointCloud b;
  {
    tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
    b = voxel_downsample(big, 0.25);
  }
  ASSERT_EQ(a.size(), b.size());
  for (size_t i = 0; i < a.size(); ++i) ASSERT_EQ(a.points[i], b.points[i]);
  EXPECT_LT(a.size(), big.size());

  // Against a plain ordered map of voxels: same voxels, same lexicographic order, same means.
  std::map<std::array<int64_t, 3>, std::pair<Eigen::Vector3d, int>> reference;
  for (const Eigen::Vector3f& p : big.points) {
    const std::array<int64_t, 3> key{static_cast<int64_t>(std::floor(p.x() / 0.25)),
                                     static_cast<int64_t>(std::floor(p.y() / 0.25)),
                                     static_cast<int64_t>(std::floor(p.z() / 0.25))};
    auto& [sum, count] = reference.try_emplace(key, Eigen::Vector3d::Zero(), 0).first->second;
    sum += p.cast<double>();
    ++count;
  }
  ASSERT_EQ(a.size(), reference.size());
  size_t i = 0;
  for (const auto& [key, acc] : reference) {
    ASSERT_LT((a.points[i++].cast<double>() - acc.first / acc.second).norm(), 1e-5) << i;
  }
}

TEST(Downsample, ExactFarFromOrigin) {
  // +-100 km at 5 cm: points in distinct voxels stay distinct, points of one voxel merge.
  PointCloud c;
  for (double base : {-100000.0, 100000.0}) {
    c.points.push_back(Eigen::Vector3f(base + 0.01, base + 0.01, 0.01));
    c.points.push_back(Eigen::Vector3f(base + 0.02, base + 0.02, 0.02));
    c.points.push_back(Eigen::Vector3f(base + 0.5, base + 0.5, 0.5));
  }
  const PointCloud d = voxel_downsample(c, 0.05);
  EXPECT_EQ(d.size(), 4u);
  EXPECT_NEAR(d.points[0].x(), -100000.0 + 0.015, 0.01);
}

namespace {

// The k nearest by brute force: squared distances, ascending.
std::vector<float> brute_knn(const std::vector<Eigen::Vector3f>& pts, const Eigen::Vector3f& q, size_t k) {
  std::vector<float> d;
  for (const Eigen::Vector3f& p : pts) d.push_back((p - q).squaredNorm());
  std::sort(d.begin(), d.end());
  d.resize(std::min(k, d.size()));
  return d;
}

}  // namespace

// Exact search on the shapes a scan has: a dense plane, far sparse rings, duplicates, a flat (2D) cloud,
// and points spaced geometrically.
TEST(KdTree, FindsExactlyTheNearestOnScanLikeAndAdversarialClouds) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  std::vector<std::vector<Eigen::Vector3f>> clouds(4);
  for (int i = 0; i < 3000; ++i) clouds[0].emplace_back(20 * u(rng), 20 * u(rng), 0.02f * u(rng));
  for (int r = 0; r < 8; ++r) {
    for (int a = 0; a < 400; ++a) {
      const float t = a * 2 * M_PI / 400, range = 10.0f + 7.0f * r;
      clouds[0].emplace_back(range * std::cos(t), range * std::sin(t), -1.7f);
    }
  }
  for (int i = 0; i < 500; ++i) clouds[1].push_back(Eigen::Vector3f(1, 2, 3) + 0.5f * Eigen::Vector3f(i % 3, 0, 0));
  for (int i = 0; i < 2000; ++i) clouds[2].emplace_back(50 * u(rng), 50 * u(rng), 0.0f);
  for (int i = 0; i < 200; ++i) clouds[3].emplace_back(std::ldexp(1.0f, -i / 2), 0.0f, (i % 2) * 1e-3f);
  for (const auto& pts : clouds) {
    const KdTree tree(pts);
    for (size_t k : {1u, 5u, 20u, 600u}) {
      std::vector<uint32_t> idx(k);
      std::vector<float> sq(k);
      for (int t = 0; t < 50; ++t) {
        const Eigen::Vector3f q = t % 2 ? pts[rng() % pts.size()] : Eigen::Vector3f(30 * u(rng), 30 * u(rng), u(rng));
        const size_t found = tree.knn(q, k, idx.data(), sq.data());
        const std::vector<float> expected = brute_knn(pts, q, k);
        ASSERT_EQ(found, expected.size());
        for (size_t j = 0; j < found; ++j) {
          EXPECT_FLOAT_EQ(sq[j], expected[j]);
          EXPECT_FLOAT_EQ(sq[j], (pts[idx[j]] - q).squaredNorm());
        }
      }
    }
  }
  const std::vector<Eigen::Vector3f> none;
  const KdTree empty(none);
  uint32_t i;
  float d;
  EXPECT_EQ(empty.knn(Eigen::Vector3f::Zero(), 3, &i, &d), 0u);
}

TEST(Covariance, PlaneLikeOnAPlaneAndSafeOnTinyClouds) {
  PointCloud plane;
  std::mt19937_64 rng(4);
  std::uniform_real_distribution<float> u(-5.f, 5.f);
  for (int i = 0; i < 2000; ++i) plane.points.emplace_back(u(rng), u(rng), 0.3f * 1.0f);
  estimate_covariances(plane);
  for (size_t i = 0; i < plane.size(); i += 97) {
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3f> eig(plane.covs[i]);
    EXPECT_NEAR(eig.eigenvalues()[0], 1e-3, 1e-5);
    EXPECT_NEAR(eig.eigenvalues()[1], 1.0, 1e-4);
    EXPECT_NEAR(std::abs(eig.eigenvectors().col(0).z()), 1.0, 1e-4);  // normal is z
  }
  PointCloud tiny;
  tiny.points = {{0, 0, 0}, {1, 0, 0}};
  estimate_covariances(tiny);
  ASSERT_EQ(tiny.covs.size(), 2u);
  EXPECT_TRUE(tiny.covs[0].allFinite());
  EXPECT_GT(tiny.covs[0].determinant(), 0.f);
}

// preprocess.plane_epsilon reaches the covariances every registration reads.
TEST(Covariance, ThePlaneEpsilonOfTheScanPreprocessing) {
  PointCloud plane;
  std::mt19937_64 rng(6);
  std::uniform_real_distribution<float> u(-30.f, 30.f);
  for (int i = 0; i < 20000; ++i) plane.points.emplace_back(u(rng), u(rng), -1.7f);
  for (const double epsilon : {1e-3, 1e-5}) {
    PreprocessConfig config;
    config.plane_epsilon = epsilon;
    const PointCloud c = preprocess_scan(plane, config, nullptr);
    ASSERT_GT(c.size(), 1000u);
    for (size_t i = 0; i < c.size(); i += 101) {
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix3f> eig(c.covs[i]);
      EXPECT_NEAR(eig.eigenvalues()[0], epsilon, 0.01 * epsilon) << i;
      EXPECT_NEAR(std::abs(eig.eigenvectors().col(0).z()), 1.0, 1e-4);
    }
  }
}

// A beam whose elevation is off by d moves its point by range * d along the vertical plane of
// the beam: on far ground that is nearly the surface normal, where plane-like covariances are
// thinnest, so the uncertainty is added there (preprocess.elevation_sigma_deg).
// Each point's covariance is that of its k nearest as brute force finds them.
TEST(Covariance, FromTheExactNearestNeighbours) {
  PointCloud cloud = voxel_downsample(make_structured_scene(20000, 9), 0.25);
  CovarianceConfig config;
  config.num_neighbors = 20;
  estimate_covariances(cloud, config);
  for (size_t i = 0; i < cloud.size(); i += 37) {
    std::vector<std::pair<float, size_t>> d;
    for (size_t j = 0; j < cloud.size(); ++j) d.push_back({(cloud.points[j] - cloud.points[i]).squaredNorm(), j});
    std::partial_sort(d.begin(), d.begin() + 20, d.end());
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (int j = 0; j < 20; ++j) mean += cloud.points[d[j].second].cast<double>() / 20.0;
    Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
    for (int j = 0; j < 20; ++j) {
      const Eigen::Vector3d e = cloud.points[d[j].second].cast<double>() - mean;
      cov += e * e.transpose() / 20.0;
    }
    const Eigen::Matrix3d U = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(cov).eigenvectors();
    const Eigen::Matrix3d expected = U * Eigen::Vector3d(config.epsilon, 1.0, 1.0).asDiagonal() * U.transpose();
    EXPECT_LT((cloud.covs[i].cast<double>() - expected).norm(), 1e-5) << i;
  }
}

TEST(Covariance, ElevationUncertaintyGrowsWithRangeAlongTheBeamsVerticalPlane) {
  PointCloud ground;
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<float> u(-40.f, 40.f);
  for (int i = 0; i < 20000; ++i) ground.points.emplace_back(u(rng), u(rng), -1.7f);
  PointCloud with = ground;
  estimate_covariances(ground);
  CovarianceConfig config;
  config.elevation_sigma = 0.2 * M_PI / 180.0;
  estimate_covariances(with, config);
  double near = 0.0, far = 0.0;
  for (size_t i = 0; i < ground.size(); i += 53) {
    const Eigen::Vector3d p = ground.points[i].cast<double>();
    const double h = p.head<2>().norm();
    const Eigen::Vector3d v(-p.z() * p.x() / h, -p.z() * p.y() / h, h);  // d p / d elevation
    const Eigen::Matrix3d added = (with.covs[i] - ground.covs[i]).cast<double>();
    EXPECT_LT((added - config.elevation_sigma * config.elevation_sigma * v * v.transpose()).norm(), 1e-5) << p.transpose();
    const double vertical = with.covs[i](2, 2);
    if (h < 10.0) near = std::max(near, vertical);
    if (h > 30.0) far = far == 0.0 ? vertical : std::min(far, vertical);
  }
  EXPECT_GT(far, 4.0 * near);  // far ground weighs less in height than near ground
}

TEST(VoxelMap, StoresMeanOfMeansAndMeanOfCovariances) {
  PointCloud c;
  c.points = {{0.1f, 0.1f, 0.1f}, {0.3f, 0.2f, 0.1f}, {1.5f, 0.1f, 0.1f}};
  c.covs = {Eigen::Matrix3f::Identity(), 3.f * Eigen::Matrix3f::Identity(), Eigen::Matrix3f::Identity()};
  GaussianVoxelMap map(1.0);
  map.insert(c);
  map.finalize();
  ASSERT_EQ(map.num_voxels(), 2u);
  const int v = map.lookup({0.9f, 0.9f, 0.9f});
  ASSERT_GE(v, 0);
  EXPECT_EQ(map.count(v), 2);
  EXPECT_TRUE(map.mean(v).isApprox(Eigen::Vector3f(0.2f, 0.15f, 0.1f)));
  EXPECT_TRUE(map.cov(v).isApprox(2.f * Eigen::Matrix3f::Identity()));
  EXPECT_EQ(map.lookup({-0.1f, 0.5f, 0.5f}), -1);
}

TEST(VoxelMap, NoPointLostAtHighLoad) {
  // Many voxels force several rehashes; every voxel must stay findable with the right count.
  PointCloud c;
  for (int x = -60; x < 60; ++x)
    for (int y = -60; y < 60; ++y)
      for (int z = 0; z < 3; ++z) c.points.emplace_back(x + 0.5f, y + 0.5f, z + 0.5f);
  c.covs.assign(c.size(), Eigen::Matrix3f::Identity());
  GaussianVoxelMap map(1.0);
  map.insert(c);
  map.insert(c);
  map.finalize();
  EXPECT_EQ(map.num_voxels(), c.size());
  for (size_t i = 0; i < c.size(); ++i) {
    const int v = map.lookup(c.points[i]);
    ASSERT_GE(v, 0);
    ASSERT_EQ(map.count(v), 2);
  }
}

TEST(VoxelMap, RemovingACloudLeavesTheMapOfTheOthers) {
  // A sliding window: clouds 0..3 in, 0 and 1 out, against a map of 2 and 3 built afresh.
  std::vector<PointCloud> clouds;
  std::vector<Eigen::Isometry3d> poses;
  for (int k = 0; k < 4; ++k) {
    PointCloud c = make_structured_scene(3000, 20 + k);
    c.covs.assign(c.size(), Eigen::Matrix3f::Zero());
    for (size_t i = 0; i < c.size(); ++i) c.covs[i].diagonal() = Eigen::Vector3f(0.01f * (i % 7 + 1), 0.02f, 0.03f);
    clouds.push_back(std::move(c));
    poses.push_back(Eigen::Translation3d(1000.0 + 0.7 * k, -500.0, 3.0) * Eigen::AngleAxisd(0.2 * k, Eigen::Vector3d::UnitZ()));
  }
  GaussianVoxelMap window(1.0, GaussianVoxelMap::Updates::incremental), fresh(1.0);
  for (int k = 0; k < 4; ++k) window.insert(clouds[k], poses[k]);
  window.finalize();
  const size_t all_voxels = window.num_voxels();
  window.remove(clouds[0], poses[0]);
  window.remove(clouds[1], poses[1]);
  window.finalize();
  for (int k = 2; k < 4; ++k) fresh.insert(clouds[k], poses[k]);
  fresh.finalize();
  ASSERT_EQ(window.num_voxels(), fresh.num_voxels());
  EXPECT_LT(window.num_voxels(), all_voxels);  // the emptied voxels are gone, not kept at zero
  for (size_t v = 0; v < fresh.num_voxels(); ++v) {
    const int w = window.find(fresh.coord(static_cast<int>(v)));
    ASSERT_GE(w, 0);
    EXPECT_EQ(window.count(w), fresh.count(static_cast<int>(v)));
    EXPECT_LT((window.mean(w) - fresh.mean(static_cast<int>(v))).norm(), 1e-3f);  // float ulp at 1 km
    EXPECT_LT((window.cov(w) - fresh.cov(static_cast<int>(v))).norm(), 1e-6f);
  }
  GaussianVoxelMap empty(1.0, GaussianVoxelMap::Updates::incremental);
  EXPECT_THROW(empty.remove(clouds[0], poses[0]), Error);
  // A map built once keeps no accumulators to take a cloud out of, or to add one to.
  GaussianVoxelMap kept(1.0, GaussianVoxelMap::Updates::incremental);
  for (int k = 2; k < 4; ++k) kept.insert(clouds[k], poses[k]);
  kept.finalize();
  EXPECT_LT(fresh.memory_bytes(), 0.7 * kept.memory_bytes());
  EXPECT_THROW(fresh.remove(clouds[2], poses[2]), Error);
  EXPECT_THROW(fresh.insert(clouds[0], poses[0]), Error);
}

TEST(Overlap, FractionOfSourcePointsInOccupiedVoxels) {
  PointCloud target;
  for (int i = 0; i < 10; ++i) target.points.emplace_back(i + 0.5f, 0.5f, 0.5f);
  target.covs.assign(target.size(), Eigen::Matrix3f::Identity());
  GaussianVoxelMap map(1.0);
  map.insert(target);
  map.finalize();
  PointCloud source;
  for (int i = 0; i < 20; ++i) source.points.emplace_back(i + 0.5f, 0.5f, 0.5f);
  EXPECT_DOUBLE_EQ(overlap(source, map, Eigen::Isometry3d::Identity()), 0.5);
  Eigen::Isometry3d shift = Eigen::Isometry3d::Identity();
  shift.translation().x() = -5.0;  // points 5..14 land on 0..9
  EXPECT_DOUBLE_EQ(overlap(source, map, shift), 0.5);
  shift.translation().y() = 3.0;
  EXPECT_DOUBLE_EQ(overlap(source, map, shift), 0.0);
}

TEST(VoxelMap, BoundsAreTheBoxOfTheVoxelsCells) {
  PointCloud c = make_structured_scene(4000, 3);
  c.covs.assign(c.size(), Eigen::Matrix3f::Identity() * 0.01f);
  GaussianVoxelMap map(0.5);
  EXPECT_TRUE(map.bounds().isEmpty());
  const Eigen::Isometry3d T = Eigen::Translation3d(300.0, -40.0, 2.0) * Eigen::AngleAxisd(0.7, Eigen::Vector3d::UnitZ());
  map.insert(c, T);
  map.finalize();
  Eigen::Vector3i lo = map.coord(0), hi = map.coord(0);
  for (size_t v = 0; v < map.num_voxels(); ++v) {
    lo = lo.cwiseMin(map.coord(static_cast<int>(v)));
    hi = hi.cwiseMax(map.coord(static_cast<int>(v)));
  }
  EXPECT_TRUE(map.bounds().min().isApprox(lo.cast<float>() * 0.5f));
  EXPECT_TRUE(map.bounds().max().isApprox((hi + Eigen::Vector3i::Ones()).cast<float>() * 0.5f));
  for (const Eigen::Vector3f& p : c.points) EXPECT_TRUE(map.bounds().contains((T * p.cast<double>()).cast<float>()));
}

TEST(Overlap, BoxesRuleOutOnlyPosesNoSourcePointCanReach) {
  PointCloud t = make_structured_scene(4000, 4), source = make_structured_scene(3000, 5);
  t.covs.assign(t.size(), Eigen::Matrix3f::Identity() * 0.01f);
  GaussianVoxelMap map(1.0);
  map.insert(t);
  map.finalize();
  const Eigen::AlignedBox3f box = bounding_box(source);
  ASSERT_FALSE(box.isEmpty());
  for (const Eigen::Vector3f& p : source.points) ASSERT_TRUE(box.contains(p));
  // Sweeps of the source out of the target's box along several headings, in 0.25 m steps, turned
  // as it goes: wherever the boxes rule a pose out, no point may hit a voxel there.
  int ruled_out = 0;
  for (int heading = 0; heading < 8; ++heading) {
    const Eigen::Vector3d dir =
        Eigen::AngleAxisd(0.8 * heading, Eigen::Vector3d::UnitZ()) * Eigen::Vector3d(1.0, 0.0, 0.1 * heading - 0.3);
    for (double d = 0.0; d < 80.0; d += 0.25) {
      const Eigen::Isometry3d T =
          Eigen::Translation3d(d * dir.normalized()) * Eigen::AngleAxisd(0.05 * d, Eigen::Vector3d::UnitZ());
      if (may_overlap(box, map, T)) continue;
      ++ruled_out;
      EXPECT_EQ(overlap(source, map, T), 0.0) << "heading " << heading << ", " << d << " m";
    }
  }
  EXPECT_GT(ruled_out, 8 * 100) << "out of 8 x 320 poses, the farther half at least";
  EXPECT_TRUE(may_overlap(box, map, Eigen::Isometry3d::Identity()));
  EXPECT_FALSE(may_overlap(Eigen::AlignedBox3f(), map, Eigen::Isometry3d::Identity()));
  EXPECT_FALSE(may_overlap(box, GaussianVoxelMap(1.0), Eigen::Isometry3d::Identity()));
}

}  // namespace
}  // namespace gcmap
