// Re-linearize only what moved (graph/lazy_backend.hpp) against re-linearizing every factor.
#include <cstdio>

#include "gcmap/core/error.hpp"
#include "gcmap/core/preprocess.hpp"
#include "gcmap/graph/lazy_backend.hpp"
#include "gcmap/graph/levenberg_marquardt.hpp"
#include "gcmap/graph/matching_graph.hpp"
#include "gcmap/mapping/config.hpp"
#include "gcmap/sim/synthetic.hpp"
#include "test_util.hpp"

namespace gcmap {
namespace {

// Frames around one synthetic scene, each with its own sampling, and a perturbed start.
struct Scene {
  std::vector<ScanNode> nodes;
  std::vector<Eigen::Isometry3d> truth;
  Values start;
};

Scene make_scene(int frames) {
  std::mt19937_64 rng(31);
  Scene s;
  for (int k = 0; k < frames; ++k) {
    s.truth.push_back(k == 0 ? Eigen::Isometry3d::Identity() : test::random_pose(rng, 0.2, 2.0));
    PointCloud c = transformed(voxel_downsample(make_structured_scene(15000, 300 + k), 0.25), s.truth[k].inverse());
    estimate_covariances(c);
    s.nodes.push_back(make_scan_node(std::move(c), 0.5));
    s.start[k] = k == 0 ? s.truth[0] : s.truth[k] * test::random_pose(rng, 0.03, 0.15);
  }
  return s;
}

// Warm-started insertions as the global mapper runs them: frame k joins with factors to every
// earlier frame it overlaps, then LM over all (frame 0 fixed). Fresh factor objects per call.
Values insert_one_by_one(const Scene& s, std::shared_ptr<LinearizationBackend> backend) {
  FactorGraph graph;
  Values values{{0, s.start.at(0)}};
  LevenbergMarquardt lm({}, std::move(backend));
  for (int k = 1; k < static_cast<int>(s.nodes.size()); ++k) {
    values[k] = s.start.at(k);
    for (int j = 0; j < k; ++j) {
      const Eigen::Isometry3d T_target_source = values[j].inverse() * values[k];
      if (overlap(*s.nodes[k].cloud, *s.nodes[j].voxels, T_target_source) >= 0.025)
        graph.add(std::make_shared<MatchingCostFactor>(k, j, s.nodes[k].cloud, s.nodes[j].voxels));
    }
    lm.optimize(graph, values, {0});
  }
  return values;
}

TEST(LazyBackend, ThresholdZeroGivesTheResultOfAlwaysRelinearizing) {
  const Scene s = make_scene(6);
  const Values always = insert_one_by_one(s, std::make_shared<CpuBackend>());
  auto lazy = std::make_shared<LazyBackend>(std::make_shared<CpuBackend>(), 0.0);
  const Values zero = insert_one_by_one(s, lazy);
  for (int k = 0; k < 6; ++k) {
    EXPECT_LT(test::translation_error(zero.at(k), always.at(k)), 1e-9) << k;
    EXPECT_LT(test::rotation_error_deg(zero.at(k), always.at(k)), 1e-7) << k;
  }
}

TEST(LazyBackend, DefaultThresholdStaysCloseAndLinearizesLess) {
  const Scene s = make_scene(8);
  // Threshold 0 stands for always re-linearizing (test above) and counts its linearizations.
  auto counting = std::make_shared<LazyBackend>(std::make_shared<CpuBackend>(), 0.0);
  const Values always = insert_one_by_one(s, counting);
  auto lazy = std::make_shared<LazyBackend>(std::make_shared<CpuBackend>(), GlobalMappingConfig{}.relinearize_threshold);
  const Values moved = insert_one_by_one(s, lazy);
  EXPECT_GT(lazy->reused(), 0u);
  EXPECT_LT(lazy->linearized(), counting->linearized());
  // Stated tolerance of the default on this scene (0.5 m voxels): 2 cm, 0.02 deg from always
  // re-linearizing, both within 2 cm of the truth (always itself sits about 1.4 cm from it here).
  double worst_to_always = 0.0, worst_to_truth = 0.0;
  for (int k = 0; k < 8; ++k) {
    EXPECT_LT(test::translation_error(moved.at(k), s.truth[k]), 0.02) << k;
    EXPECT_LT(test::translation_error(always.at(k), s.truth[k]), 0.02) << k;
    EXPECT_LT(test::translation_error(moved.at(k), always.at(k)), 0.02) << k;
    EXPECT_LT(test::rotation_error_deg(moved.at(k), always.at(k)), 0.02) << k;
    worst_to_always = std::max(worst_to_always, test::translation_error(moved.at(k), always.at(k)));
    worst_to_truth = std::max(worst_to_truth, test::translation_error(moved.at(k), s.truth[k]));
  }
  std::printf("lazy vs always: %.4f m, lazy vs truth: %.4f m; %zu linearizations (always: %zu), %zu reused\n", worst_to_always,
              worst_to_truth, lazy->linearized(), counting->linearized(), lazy->reused());
}

TEST(LazyBackend, KeptModelIsTheLinearizationCarriedToTheNewPoses) {
  // A reused factor's blocks at poses moved by d are error + 2 b.d + d.H.d, b + H d, H: compare
  // with the factor linearized afresh there, for a small motion.
  const Scene s = make_scene(2);
  auto factor = std::make_shared<MatchingCostFactor>(1, 0, s.nodes[1].cloud, s.nodes[0].voxels);
  Factor* const factors[1] = {factor.get()};
  Eigen::Isometry3d T0 = s.truth[0], T1 = s.truth[1];
  LazyBackend lazy(std::make_shared<CpuBackend>(), 0.05);
  FactorLinearization first, reused, fresh;
  const FactorPoses at0[1] = {FactorPoses{&T1, &T0}};
  lazy.linearize(factors, at0, {&first, 1});
  const Eigen::Isometry3d T1_moved = T1 * se3_exp((Vector6d() << 1e-3, -2e-3, 1e-3, 0.01, 0.005, -0.01).finished());
  const FactorPoses at1[1] = {FactorPoses{&T1_moved, &T0}};
  lazy.linearize(factors, at1, {&reused, 1});
  EXPECT_EQ(lazy.linearized(), 1u);
  EXPECT_EQ(lazy.reused(), 1u);
  EXPECT_EQ(Matrix6d(reused.H.topLeftCorner<6, 6>()), Matrix6d(first.H.topLeftCorner<6, 6>()));
  EXPECT_GT((reused.b - first.b).norm(), 0.0);
  CpuBackend().linearize(factors, at1, {&fresh, 1});
  // Re-association moves some points to other voxels, so the agreement is partial: measured, the
  // model carries 91 % of the change of b and 97.5 % of the change of the error.
  EXPECT_LT((reused.b - fresh.b).norm(), 0.2 * (fresh.b - first.b).norm());
  EXPECT_LT(std::abs(reused.error - fresh.error), 0.1 * std::abs(fresh.error - first.error));
  // Beyond the threshold the factor is linearized afresh.
  const Eigen::Isometry3d T1_far = T1 * se3_exp((Vector6d() << 0, 0, 0.1, 0, 0, 0).finished());
  const FactorPoses at2[1] = {FactorPoses{&T1_far, &T0}};
  FactorLinearization far;
  lazy.linearize(factors, at2, {&far, 1});
  EXPECT_EQ(lazy.linearized(), 2u);
}

// The force a factor's gradient b exerts on a motion exp(delta) that both its poses share:
// sum_i b_i . Ad(T_i^-1) delta, per direction of delta.
Vector6d shared_motion_force(const FactorLinearization& l, const Eigen::Isometry3d& T0, const Eigen::Isometry3d& T1) {
  return adjoint(T0.inverse()).transpose() * l.b.head<6>() + adjoint(T1.inverse()).transpose() * l.b.tail<6>();
}

TEST(LazyBackend, AKeptModelFeelsNoForceFromAMotionBothPosesShare) {
  // A matching cost depends on the relative pose alone, so turning and moving both poses together
  // changes nothing: its model must agree, even after the relative pose moved under the threshold
  // and far from the origin, where a kept Jacobian's error is multiplied by the lever arm (a map
  // levelled only by gravity turned by 8 deg under that force).
  const Scene s = make_scene(2);
  auto factor = std::make_shared<MatchingCostFactor>(1, 0, s.nodes[1].cloud, s.nodes[0].voxels);
  Factor* const factors[1] = {factor.get()};
  const Eigen::Isometry3d T0 = s.truth[0], T1 = s.truth[1];
  LazyBackend lazy(std::make_shared<CpuBackend>(), 0.05);
  FactorLinearization first, reused;
  const FactorPoses at0[1] = {FactorPoses{&T1, &T0}};
  lazy.linearize(factors, at0, {&first, 1});
  const Eigen::Isometry3d G = se3_exp((Vector6d() << 0.1, -0.3, 0.2, 300.0, -200.0, 50.0).finished());
  const Eigen::Isometry3d T0_moved = G * T0;
  const Eigen::Isometry3d T1_moved = G * T1 * se3_exp((Vector6d() << 5e-3, -5e-3, 5e-3, 0.02, 0.01, -0.02).finished());
  const FactorPoses at1[1] = {FactorPoses{&T1_moved, &T0_moved}};
  lazy.linearize(factors, at1, {&reused, 1});
  ASSERT_EQ(lazy.reused(), 1u);
  const double scale = reused.b.head<6>().norm() * (T1_moved.translation().norm() + 1.0);
  const Vector6d force = shared_motion_force(reused, T1_moved, T0_moved);
  EXPECT_LT(force.norm(), 1e-9 * scale) << force.transpose();
  // The factor linearized afresh there feels none either.
  FactorLinearization fresh;
  CpuBackend().linearize(factors, at1, {&fresh, 1});
  EXPECT_LT(shared_motion_force(fresh, T1_moved, T0_moved).norm(), 1e-6 * scale);
}

TEST(LazyBackend, OverBudgetTheFactorsThatMovedMostAreLinearizedFirst) {
  const Scene s = make_scene(2);
  std::vector<std::shared_ptr<MatchingCostFactor>> owned;
  for (int i = 0; i < 3; ++i) owned.push_back(std::make_shared<MatchingCostFactor>(1, 0, s.nodes[1].cloud, s.nodes[0].voxels));
  Factor* const factors[3] = {owned[0].get(), owned[1].get(), owned[2].get()};
  const Eigen::Isometry3d T0 = s.truth[0], T1 = s.truth[1];
  LazyBackend lazy(std::make_shared<CpuBackend>(), 0.01);
  lazy.set_max_relinearizations(1);
  std::vector<FactorLinearization> out(3);
  // Factors without a model are linearized whatever the budget.
  const FactorPoses at_start[3] = {FactorPoses{&T1, &T0}, FactorPoses{&T1, &T0}, FactorPoses{&T1, &T0}};
  lazy.linearize(factors, at_start, out);
  EXPECT_EQ(lazy.linearized(), 3u);
  const FactorLinearization first = out[0];
  // All three move past the threshold, by 2, 5 and 3 cm: only the 5 cm one is linearized anew.
  const auto shifted = [&](double x) { return T1 * se3_exp((Vector6d() << 0, 0, 0, x, 0, 0).finished()); };
  const Eigen::Isometry3d moved[3] = {shifted(0.02), shifted(0.05), shifted(0.03)};
  const FactorPoses at_moved[3] = {FactorPoses{&moved[0], &T0}, FactorPoses{&moved[1], &T0}, FactorPoses{&moved[2], &T0}};
  lazy.linearize(factors, at_moved, out);
  EXPECT_EQ(lazy.linearized(), 4u);
  EXPECT_EQ(lazy.reused(), 2u);
  EXPECT_EQ(lazy.deferred(), 2u);
  FactorLinearization fresh;
  CpuBackend().linearize({&factors[1], 1}, {&at_moved[1], 1}, {&fresh, 1});
  EXPECT_EQ(out[1].H, fresh.H);
  EXPECT_EQ(out[1].error, fresh.error);
  const auto relative_block = [](const FactorLinearization& l) { return Matrix6d(l.H.topLeftCorner<6, 6>()); };
  EXPECT_EQ(relative_block(out[0]), relative_block(first));  // deferred: its model stands in
  EXPECT_EQ(relative_block(out[2]), relative_block(first));
  // The next call takes the deferred one that moved most (3 cm), then the last; unlimited, both.
  lazy.linearize(factors, at_moved, out);
  EXPECT_EQ(lazy.linearized(), 5u);
  EXPECT_EQ(relative_block(out[0]), relative_block(first));
  EXPECT_NE(relative_block(out[2]), relative_block(first));
  lazy.set_max_relinearizations(0);
  lazy.linearize(factors, at_moved, out);
  EXPECT_EQ(lazy.linearized(), 6u);
  EXPECT_EQ(lazy.deferred(), 3u);
}

TEST(MappingConfig, MaxRelinearizationsKey) {
  EXPECT_EQ(MappingConfig{}.global.max_relinearizations, 0);  // no limit unless asked for
  EXPECT_EQ(MappingConfig::parse("global:\n  max_relinearizations: 200\n", "c.yaml").global.max_relinearizations, 200);
  try {
    MappingConfig::parse("global:\n  max_relinearizations: -1\n", "c.yaml");
    ADD_FAILURE();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("global.max_relinearizations"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace gcmap
