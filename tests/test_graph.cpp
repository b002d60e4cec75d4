#include <atomic>
#include <limits>

#include "gcmap/core/error.hpp"
#include "gcmap/core/preprocess.hpp"
#include "gcmap/graph/levenberg_marquardt.hpp"
#include "gcmap/graph/matching_graph.hpp"
#include "gcmap/io/point_cloud_io.hpp"
#include "gcmap/io/trajectory_io.hpp"
#include "gcmap/registration/vgicp.hpp"
#include "gcmap/sim/synthetic.hpp"
#include "test_util.hpp"

namespace gcmap {
namespace {

TEST(RobustKernel, HandComputedWeights) {
  EXPECT_DOUBLE_EQ(RobustKernel::none().weight(123.0), 1.0);
  EXPECT_DOUBLE_EQ(RobustKernel::huber(2.0).weight(1.5), 1.0);
  EXPECT_DOUBLE_EQ(RobustKernel::huber(2.0).weight(8.0), 0.25);
  // tukey(x, w) = max(0, 1 - x^2/w)^2
  EXPECT_DOUBLE_EQ(tukey_weight(1.0, 4.0), 0.5625);
  EXPECT_DOUBLE_EQ(tukey_weight(3.0, 4.0), 0.0);
  const RobustKernel st = RobustKernel::shifted_tukey(4.0, 5.0);
  EXPECT_DOUBLE_EQ(st.weight(5.0), 1.0);     // peak at the offset
  EXPECT_DOUBLE_EQ(st.weight(4.0), 0.5625);  // |4-5| = 1
  EXPECT_DOUBLE_EQ(st.weight(6.0), 0.5625);
  EXPECT_DOUBLE_EQ(st.weight(0.5), 0.0);   // satisfied: stops pulling
  EXPECT_DOUBLE_EQ(st.weight(20.0), 0.0);  // grossly wrong: ignored
  EXPECT_THROW(RobustKernel::parse("cauchy", 1.0, 0.0), Error);
}

// A structured scene (0.25 m apart) as the target at the origin on 0.5 m voxels and as the source
// seen from a random T_truth; equal seeds sample the same points.
struct ScenePair {
  Eigen::Isometry3d T_truth;
  std::shared_ptr<const PointCloud> source;
  ScanNode target;
};
ScenePair scene_pair(std::mt19937_64& rng, uint64_t target_seed, uint64_t source_seed) {
  PointCloud target = voxel_downsample(make_structured_scene(15000, target_seed), 0.25);
  estimate_covariances(target);
  const Eigen::Isometry3d T_truth = test::random_pose(rng, 0.1, 1.0);
  PointCloud source = transformed(voxel_downsample(make_structured_scene(15000, source_seed), 0.25), T_truth.inverse());
  estimate_covariances(source);
  return {T_truth, std::make_shared<const PointCloud>(std::move(source)), make_scan_node(std::move(target), 0.5)};
}

// Kept associations must give exactly the trial errors of looking the voxels up again at the
// linearization's pose, and those must differ from a fresh association where points change voxels.
TEST(MatchingCostFactor, KeptAssociationsGiveTheSameTrialErrors) {
  std::mt19937_64 rng(17);
  const auto [T_truth, src, target] = scene_pair(rng, 71, 72);
  MatchingCostFactor looked_up(1, 0, src, target.voxels), kept(1, 0, src, target.voxels, TrialVoxels::kept);
  const Eigen::Isometry3d T0 = Eigen::Isometry3d::Identity();
  const Eigen::Isometry3d T_lin = T_truth * test::random_pose(rng, 0.02, 0.05);
  // Before any linearization both look the voxels up at the identity.
  const Eigen::Isometry3d* at_lin[2] = {&T_lin, &T0};
  EXPECT_EQ(kept.trial_error(at_lin), looked_up.trial_error(at_lin));
  FactorLinearization a, b;
  looked_up.linearize(at_lin, a);
  kept.linearize(at_lin, b);
  EXPECT_EQ(a.error, b.error);
  EXPECT_TRUE(a.H == b.H && a.b == b.b);
  for (double step : {0.01, 0.1, 0.3}) {
    const Eigen::Isometry3d T = T_lin * test::random_pose(rng, step, step);
    const Eigen::Isometry3d* at[2] = {&T, &T0};
    EXPECT_EQ(kept.trial_error(at), looked_up.trial_error(at)) << step;
    if (step == 0.3) {
      FactorLinearization fresh;
      MatchingCostFactor(1, 0, src, target.voxels).linearize(at, fresh);
      EXPECT_NE(kept.trial_error(at), fresh.error);
    }
  }
}

// A robust width weighs a factor's linearization and its trials alike (both association kinds), and
// its cost is Cauchy's: below the plain one, which a factor without the width keeps.
TEST(MatchingCostFactor, ARobustWidthWeighsTheLinearizationAndTheTrialsAlike) {
  std::mt19937_64 rng(19);
  const auto [T_truth, src, target] = scene_pair(rng, 73, 74);
  const Eigen::Isometry3d T0 = Eigen::Isometry3d::Identity();
  const Eigen::Isometry3d T_lin = T_truth * test::random_pose(rng, 0.02, 0.05);
  const Eigen::Isometry3d* at_lin[2] = {&T_lin, &T0};
  MatchingCostFactor plain(1, 0, src, target.voxels);
  FactorLinearization p;
  plain.linearize(at_lin, p);
  for (const TrialVoxels trials : {TrialVoxels::look_up, TrialVoxels::kept}) {
    MatchingCostFactor f(1, 0, src, target.voxels, trials);
    f.set_robust_width(0.25f);
    FactorLinearization lin;
    f.linearize(at_lin, lin);
    EXPECT_NEAR(f.trial_error(at_lin), lin.error, 1e-9 * lin.error);
    EXPECT_NEAR(lin.error, evaluate_vgicp(*src, *target.voxels, T_lin, T_lin, 0.25f).error, 1e-9 * lin.error);
    EXPECT_LT(lin.error, 0.9 * p.error);
    EXPECT_LT(lin.H.norm(), 0.9 * p.H.norm());
  }
}

TEST(MatchingCostFactor, AssociationsKeptPerOptimizationAreCountedAndReleased) {
  PointCloud target_cloud = voxel_downsample(make_structured_scene(15000, 71), 0.25);
  estimate_covariances(target_cloud);
  PointCloud source = voxel_downsample(make_structured_scene(15000, 72), 0.25);
  estimate_covariances(source);
  const auto src = std::make_shared<const PointCloud>(std::move(source));
  const ScanNode target = make_scan_node(std::move(target_cloud), 0.5);
  const long before = kept_associations(), n = static_cast<long>(src->size());
  const Eigen::Isometry3d T0 = Eigen::Isometry3d::Identity(), T1(Eigen::Translation3d(0.03, -0.02, 0.01));
  const Eigen::Isometry3d* at_lin[2] = {&T0, &T0};
  const Eigen::Isometry3d* at_trial[2] = {&T1, &T0};
  MatchingCostFactor looked_up(1, 0, src, target.voxels);
  FactorLinearization lin;
  looked_up.linearize(at_lin, lin);
  {
    MatchingCostFactor f(1, 0, src, target.voxels, TrialVoxels::kept_per_optimization);
    f.linearize(at_lin, lin);
    EXPECT_EQ(kept_associations(), before + n);
    f.linearize(at_lin, lin);  // again before the release: counted once
    EXPECT_EQ(kept_associations(), before + n);
    EXPECT_EQ(f.trial_error(at_trial), looked_up.trial_error(at_trial));
    f.release_trial_state();
    EXPECT_EQ(kept_associations(), before);
    EXPECT_EQ(f.trial_error(at_trial), looked_up.trial_error(at_trial));  // looked up again
    f.linearize(at_lin, lin);
    EXPECT_EQ(kept_associations(), before + n);
  }
  EXPECT_EQ(kept_associations(), before);  // the destructor releases

  // LevenbergMarquardt releases them when its call ends.
  FactorGraph graph;
  graph.add(std::make_shared<MatchingCostFactor>(1, 0, src, target.voxels, TrialVoxels::kept_per_optimization));
  Values values{{0, T0}, {1, T1}};
  LevenbergMarquardt(LMConfig{}).optimize(graph, values, {0});
  EXPECT_EQ(kept_associations(), before);
}

// The targets out of the source's reach are left out before any lookup; what is kept, and each
// overlap, must be what looking up every target's points gives.
TEST(OverlappingTargets, SkippingTargetsOutOfReachKeepsWhatLookupsFind) {
  const ScanNode node = make_scan_node(voxel_downsample(make_structured_scene(8000, 11), 0.25), 1.0);
  const auto source = std::make_shared<const PointCloud>(*node.cloud);
  std::vector<std::shared_ptr<const GaussianVoxelMap>> targets;
  std::vector<Eigen::Isometry3d> T_target_source;
  // Shifted along x in 0.5 m steps across the edge of reach (the scene's ground fills its box, so
  // points meet voxels as soon as the boxes meet), and far away.
  for (double x = 0.0; x < 1100.0; x += x < 70.0 ? 0.5 : 500.0) {
    targets.push_back(node.voxels);
    T_target_source.push_back(Eigen::Isometry3d(Eigen::Translation3d(x, 0.0, 0.0)));
  }
  CpuBackend backend;
  for (double min_overlap : {0.0, 1e-4, 0.025, 0.3}) {
    std::vector<TargetOverlap> expected;
    for (size_t k = 0; k < targets.size(); ++k) {
      const double o = overlap(*source, *targets[k], T_target_source[k]);
      if (o >= min_overlap) expected.push_back({static_cast<int>(k), o});
    }
    const std::vector<TargetOverlap> kept = overlapping_targets(backend, source, targets, T_target_source, min_overlap);
    ASSERT_EQ(kept.size(), expected.size()) << "min_overlap " << min_overlap;
    for (size_t i = 0; i < kept.size(); ++i) {
      EXPECT_EQ(kept[i].index, expected[i].index);
      EXPECT_EQ(kept[i].overlap, expected[i].overlap);
    }
    if (min_overlap == 0.0) EXPECT_EQ(kept.size(), targets.size());
    if (min_overlap == 1e-4) EXPECT_LT(kept.size(), targets.size()) << "the far targets have no overlap";
  }
}

TEST(RelativePoseFactor, JacobianMatchesNumeric) {
  std::mt19937_64 rng(9);
  const Eigen::Isometry3d Ti = test::random_pose(rng, 1.0, 5.0), Tj = test::random_pose(rng, 1.0, 5.0);
  const Eigen::Isometry3d meas = Ti.inverse() * Tj * test::random_pose(rng, 0.3, 0.5);
  Matrix6d info = Matrix6d::Identity();
  info.diagonal() << 10, 20, 30, 1, 2, 3;
  RelativePoseFactor f(0, 1, meas, info);
  const Eigen::Isometry3d* poses[2] = {&Ti, &Tj};
  FactorLinearization lin;
  f.linearize(poses, lin);
  // Numeric Jacobian of the residual.
  Eigen::Matrix<double, 6, 12> J;
  const double h = 1e-6;
  for (int k = 0; k < 12; ++k) {
    Vector6d d = Vector6d::Zero();
    d[k % 6] = h;
    const Eigen::Isometry3d ip = k < 6 ? Ti * se3_exp(d) : Ti, im = k < 6 ? Ti * se3_exp(-d) : Ti;
    const Eigen::Isometry3d jp = k < 6 ? Tj : Tj * se3_exp(d), jm = k < 6 ? Tj : Tj * se3_exp(-d);
    J.col(k) = (f.residual(ip, jp) - f.residual(im, jm)) / (2 * h);
  }
  const Vector6d e = f.residual(Ti, Tj);
  EXPECT_LT((lin.H - J.transpose() * info * J).norm(), 1e-5 * lin.H.norm());
  EXPECT_LT((lin.b - J.transpose() * info * e).norm(), 1e-5 * lin.b.norm());
  EXPECT_NEAR(lin.error, e.dot(info * e), 1e-9);
}

// A square loop of 4 poses with consistent relative measurements: the optimum is the truth.
struct PoseGraphProblem {
  std::vector<Eigen::Isometry3d> truth;
  FactorGraph graph;
  Values initial;
};

PoseGraphProblem square_loop(RobustKernel kernel, bool add_outlier) {
  PoseGraphProblem p;
  std::mt19937_64 rng(17);
  for (int k = 0; k < 4; ++k) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = so3_exp(Eigen::Vector3d(0, 0, k * M_PI / 2));
    T.translation() = T.linear() * Eigen::Vector3d(5, 0, 0);
    p.truth.push_back(T);
  }
  const Matrix6d info = Matrix6d::Identity() * 100.0;
  for (int k = 0; k < 4; ++k) {
    const int j = (k + 1) % 4;
    p.graph.add(std::make_shared<RelativePoseFactor>(k, j, p.truth[k].inverse() * p.truth[j], info, kernel));
    p.graph.add(std::make_shared<RelativePoseFactor>(k, (k + 2) % 4, p.truth[k].inverse() * p.truth[(k + 2) % 4], info, kernel));
  }
  if (add_outlier) {
    // Claims pose 2 is 4 m and 40 degrees away from where it is.
    Eigen::Isometry3d wrong = p.truth[0].inverse() * p.truth[2];
    wrong = wrong * se3_exp((Vector6d() << 0, 0, 0.7, 4.0, 0, 0).finished());
    p.graph.add(std::make_shared<RelativePoseFactor>(0, 2, wrong, info, kernel));
  }
  for (int k = 0; k < 4; ++k) p.initial[k] = k == 0 ? p.truth[0] : p.truth[k] * test::random_pose(rng, 0.15, 0.4);
  return p;
}

TEST(LevenbergMarquardt, PoseGraphReachesKnownOptimum) {
  PoseGraphProblem p = square_loop(RobustKernel::none(), false);
  LevenbergMarquardt lm;
  const LMResult r = lm.optimize(p.graph, p.initial, {0});
  EXPECT_TRUE(r.converged);
  EXPECT_LT(r.final_error, 1e-12);
  for (int k = 0; k < 4; ++k) {
    EXPECT_LT(test::translation_error(p.initial[k], p.truth[k]), 1e-6);
    EXPECT_LT(test::rotation_error_deg(p.initial[k], p.truth[k]), 1e-5);
  }
}

TEST(LevenbergMarquardt, AStopRequestEndsItAfterTheIterationUnderWayAtItsAcceptedPoses) {
  PoseGraphProblem whole = square_loop(RobustKernel::none(), false), stopped = whole;
  const LMResult all = LevenbergMarquardt().optimize(whole.graph, whole.initial, {0});
  ASSERT_GT(all.iterations, 2);
  std::atomic<bool> stop{false};
  LevenbergMarquardt lm;
  lm.stop_on(&stop);
  lm.on_iteration([&](const LMIteration&) { stop = true; });  // as a signal arriving during the first iteration
  const LMResult r = lm.optimize(stopped.graph, stopped.initial, {0});
  EXPECT_EQ(r.iterations, 1);
  EXPECT_FALSE(r.converged);
  EXPECT_LT(r.final_error, r.initial_error);
  // The poses of the one accepted step, as an optimization bounded to one iteration leaves them.
  PoseGraphProblem one = square_loop(RobustKernel::none(), false);
  LMConfig config;
  config.max_iterations = 1;
  LevenbergMarquardt(config).optimize(one.graph, one.initial, {0});
  for (int k = 0; k < 4; ++k) EXPECT_TRUE(stopped.initial.at(k).isApprox(one.initial.at(k), 1e-12));
}

TEST(LevenbergMarquardt, ShiftedTukeyRejectsOutlierConstraint) {
  // The outlier's whitened residual is ~ sqrt(100 * (0.7^2 + 4^2)) ~ 40, the inliers' start below
  // ~10: a kernel of width sqrt(w) = 20 gives the outlier zero weight and lets the inliers decide.
  PoseGraphProblem robust = square_loop(RobustKernel::shifted_tukey(400.0, 0.0), true);
  LevenbergMarquardt lm;
  lm.optimize(robust.graph, robust.initial, {0});
  for (int k = 0; k < 4; ++k) EXPECT_LT(test::translation_error(robust.initial[k], robust.truth[k]), 1e-3);
  const auto* outlier = dynamic_cast<const RelativePoseFactor*>(robust.graph.factors.back().get());
  EXPECT_EQ(outlier->weight(), 0.0);

  PoseGraphProblem plain = square_loop(RobustKernel::none(), true);
  LevenbergMarquardt lm2;
  lm2.optimize(plain.graph, plain.initial, {0});
  EXPECT_GT(test::translation_error(plain.initial[2], plain.truth[2]), 0.5);  // the outlier drags it
}

TEST(LevenbergMarquardt, StopsOnceTheModelPredictsTheGainAndLosesAtMostTheTolerance) {
  // Inconsistent measurements: the optimum keeps a positive error for the tolerance to scale with.
  PoseGraphProblem p = square_loop(RobustKernel::none(), false);
  const Eigen::Isometry3d off =
      p.truth[1].inverse() * p.truth[3] * se3_exp((Vector6d() << 0.02, 0, -0.01, 0.05, 0.1, 0).finished());
  p.graph.add(std::make_shared<RelativePoseFactor>(1, 3, off, Matrix6d::Identity() * 100.0));
  LMConfig loose_config, tight_config;
  loose_config.relative_error_tol = 1e-3;
  tight_config.relative_error_tol = tight_config.step_tol = 0.0;
  tight_config.max_iterations = 30;
  Values loose = p.initial, tight = p.initial;
  LevenbergMarquardt lm_loose(loose_config), lm_tight(tight_config);
  const LMResult rl = lm_loose.optimize(p.graph, loose, {0});
  const LMResult rt = lm_tight.optimize(p.graph, tight, {0});
  ASSERT_TRUE(rl.converged);
  EXPECT_LT(rl.iterations, rt.iterations);
  EXPECT_GT(rt.final_error, 1e-3);
  EXPECT_LE(rl.final_error, rt.final_error * (1.0 + 2e-3));
  // The last iteration does not re-linearize; the error it reports is still the cost at the result.
  double cost = 0.0;
  for (const auto& f : p.graph.factors) {
    const Eigen::Isometry3d* poses[2] = {&loose.at(f->keys()[0]), &loose.at(f->keys()[1])};
    cost += f->trial_error(poses);
  }
  EXPECT_NEAR(rl.final_error, cost, 1e-12 * cost);
}

// Matching costs re-associate: a step of decimetres that gained what its fixed-association model
// predicted leaves more to gain at the next linearization. In a graph where other factors hold
// most of the error (a long drive), that prediction is met within the tolerance; only small steps
// may stop on it.
TEST(LevenbergMarquardt, LargeStepsThatGainedWhatTheyPredictedGoOn) {
  std::mt19937_64 rng(29);
  const auto [T_truth, source, target] = scene_pair(rng, 81, 81);
  FactorGraph graph;
  graph.add(std::make_shared<MatchingCostFactor>(1, 0, source, target.voxels));
  // Elsewhere in the graph: two contradicting measurements of pose 3 against the fixed pose 2,
  // already balanced at the start, hold a constant error.
  for (double x : {-3.0, 3.0}) {
    const Eigen::Isometry3d measured(Eigen::Translation3d(x, 0.0, 0.0));
    graph.add(std::make_shared<RelativePoseFactor>(2, 3, measured, Matrix6d::Identity() * 1e4));
  }
  Values start{{0, Eigen::Isometry3d::Identity()}, {2, Eigen::Isometry3d::Identity()}, {3, Eigen::Isometry3d::Identity()}};
  start[1] = T_truth * Eigen::Translation3d(0.45, 0.0, 0.0);  // 0.9 voxels
  LMConfig config;
  config.relative_error_tol = 1e-4;  // as an insertion into the global graph
  config.max_iterations = 10;
  const auto run = [&](double predicted_stop_step, Values& values) {
    config.predicted_stop_step = predicted_stop_step;
    return LevenbergMarquardt(config).optimize(graph, values, {0, 2});
  };
  Values bounded = start, unbounded = start;
  const LMResult rb = run(LMConfig{}.predicted_stop_step, bounded);
  const LMResult ru = run(std::numeric_limits<double>::infinity(), unbounded);
  // Measured: 2 iterations, 0.03 mm from the truth; unbounded 1 iteration, 2.2 mm.
  EXPECT_GT(rb.iterations, ru.iterations);
  EXPECT_LT(test::translation_error(bounded.at(1), T_truth), 5e-4);
  EXPECT_GT(test::translation_error(unbounded.at(1), T_truth), 1e-3);
  EXPECT_LT(rb.final_error, ru.final_error);
}

TEST(LevenbergMarquardt, SingularSystemIsReported) {
  PoseGraphProblem p = square_loop(RobustKernel::none(), false);
  p.initial[7] = Eigen::Isometry3d::Identity();  // a pose no factor touches
  LevenbergMarquardt lm;
  try {
    lm.optimize(p.graph, p.initial, {0});
    ADD_FAILURE();
  } catch (const Error& e) { EXPECT_NE(std::string(e.what()).find("pose 7"), std::string::npos) << e.what(); }
  FactorGraph g;
  g.add(std::make_shared<RelativePoseFactor>(0, 9, Eigen::Isometry3d::Identity(), Matrix6d::Identity()));
  Values v{{0, Eigen::Isometry3d::Identity()}};
  EXPECT_THROW(lm.optimize(g, v, {0}), Error);
}

// The gyro's rotation between two poses weighs their relative rotation by its variance and says
// nothing of their relative translation; chained, rotations compose and variances add.
TEST(GyroRotationFactor, HoldsTheRelativeRotationAndLeavesTheTranslation) {
  const GyroRotation a{so3_exp(Eigen::Vector3d(0.0, 0.0, 0.2)), 1e-6}, b{so3_exp(Eigen::Vector3d(0.1, 0.0, 0.0)), 2e-6};
  const GyroRotation ab = a.then(b);
  EXPECT_TRUE(ab.R.isApprox(a.R * b.R, 1e-12));
  EXPECT_DOUBLE_EQ(ab.variance, 3e-6);

  const auto f = gyro_rotation_factor(0, 1, ab);
  const Eigen::Isometry3d T0 = se3_exp((Vector6d() << 0.3, -0.2, 0.1, 4.0, 5.0, 6.0).finished());
  Eigen::Isometry3d T1 = T0;
  T1.linear() = T0.linear() * ab.R;
  T1.translation() += Eigen::Vector3d(1.0, 2.0, 3.0);
  const Eigen::Isometry3d* at[2] = {&T0, &T1};
  EXPECT_NEAR(f->trial_error(at), 0.0, 1e-12);
  Eigen::Isometry3d moved = T1;
  moved.translation() += Eigen::Vector3d(-7.0, 0.5, 2.0);
  const Eigen::Isometry3d* shifted[2] = {&T0, &moved};
  EXPECT_NEAR(f->trial_error(shifted), 0.0, 1e-12);
  Eigen::Isometry3d turned = T1;
  turned.linear() = T1.linear() * so3_exp(Eigen::Vector3d(0.0, 1e-3, 0.0));
  const Eigen::Isometry3d* off[2] = {&T0, &turned};
  EXPECT_NEAR(f->trial_error(off), 1e-6 / 3e-6, 1e-9);

  // Pose 1 turned 3 deg off the gyro's rotation comes back to it; a translation-only factor holds
  // where it is.
  FactorGraph g;
  g.add(f);
  Matrix6d translation_only = Matrix6d::Zero();
  translation_only.bottomRightCorner<3, 3>() = Eigen::Matrix3d::Identity() * 100.0;
  g.add(std::make_shared<RelativePoseFactor>(0, 1, T0.inverse() * T1, translation_only));
  Values v{{0, T0}, {1, T1}};
  v[1].linear() = T1.linear() * so3_exp(Eigen::Vector3d(0.03, -0.04, 0.02));
  LevenbergMarquardt lm;
  EXPECT_TRUE(lm.optimize(g, v, {0}).converged);
  EXPECT_LT(test::rotation_error_deg(v[1], T1), 1e-5);
  EXPECT_LT(test::translation_error(v[1], T1), 1e-6);
}

// With the odometry's translation: the rotation weighs as above, the translation (in pose 0's
// frame) by translation_sigma per axis.
TEST(GyroMotionFactor, HoldsTheRelativeTranslationAtItsSigma) {
  const GyroRotation gyro{so3_exp(Eigen::Vector3d(0.0, 0.1, 0.2)), 1e-6};
  const Eigen::Vector3d t_0_1(0.5, -0.1, 0.05);
  const auto f = gyro_motion_factor(0, 1, gyro, t_0_1, 0.05);
  const Eigen::Isometry3d T0 = se3_exp((Vector6d() << 0.3, -0.2, 0.1, 4.0, 5.0, 6.0).finished());
  Eigen::Isometry3d T1 = T0;
  T1.linear() = T0.linear() * gyro.R;
  T1.translation() = T0 * t_0_1;
  const Eigen::Isometry3d* at[2] = {&T0, &T1};
  EXPECT_NEAR(f->trial_error(at), 0.0, 1e-12);
  for (int axis = 0; axis < 3; ++axis) {
    Eigen::Isometry3d moved = T1;
    moved.translation() += 0.02 * T0.linear().col(axis);  // 2 cm along pose 0's axis
    const Eigen::Isometry3d* shifted[2] = {&T0, &moved};
    EXPECT_NEAR(f->trial_error(shifted), std::pow(0.02 / 0.05, 2), 1e-6) << axis;
  }
  Eigen::Isometry3d turned = T1;
  turned.linear() = T1.linear() * so3_exp(Eigen::Vector3d(1e-3, 0.0, 0.0));
  turned.translation() = T1.translation();
  const Eigen::Isometry3d* off[2] = {&T0, &turned};
  EXPECT_NEAR(f->trial_error(off), 1e-6 / 1e-6, 1e-6);
}

// A long drive can leave a pose whose only factors say nothing at the estimate: a loop's shifted
// Tukey kernel at zero weight (here: measurement met exactly, 5 from the kernel's peak). That pose
// stays where it is; the others are optimized (city three times in a row stopped here once).
TEST(LevenbergMarquardt, APoseItsFactorsSayNothingAboutStaysPut) {
  PoseGraphProblem p = square_loop(RobustKernel::none(), false);
  p.initial[3] = p.truth[3];
  const Eigen::Isometry3d T_3_5 = se3_exp((Vector6d() << 0.1, 0.0, 0.3, 1.0, 2.0, 0.0).finished());
  p.graph.add(
      std::make_shared<RelativePoseFactor>(3, 5, T_3_5, Matrix6d::Identity() * 100.0, RobustKernel::shifted_tukey(4.0, 5.0)));
  p.initial[5] = p.initial[3] * T_3_5;
  const Eigen::Isometry3d start5 = p.initial[5];
  LevenbergMarquardt lm;
  const LMResult r = lm.optimize(p.graph, p.initial, {0, 3});
  EXPECT_TRUE(r.converged);
  EXPECT_TRUE(p.initial[5].isApprox(start5, 1e-12));
  for (int k = 1; k < 3; ++k) EXPECT_LT(test::translation_error(p.initial[k], p.truth[k]), 1e-6) << k;
}

// A fully connected graph of 10 synthetic frames around one scene.
TEST(LevenbergMarquardt, SyntheticTenFramesConvergeToGroundTruth) {
  std::mt19937_64 rng(23);
  std::vector<ScanNode> nodes;
  std::vector<Eigen::Isometry3d> truth;
  Values values;
  for (int k = 0; k < 10; ++k) {
    truth.push_back(k == 0 ? Eigen::Isometry3d::Identity() : test::random_pose(rng, 0.2, 2.0));
    // Every frame sees the same surfaces with its own sampling, expressed in its own frame.
    PointCloud c = transformed(voxel_downsample(make_structured_scene(20000, 100 + k), 0.25), truth[k].inverse());
    estimate_covariances(c);
    auto v = std::make_shared<GaussianVoxelMap>(0.5);
    v->insert(c);
    v->finalize();
    nodes.push_back({std::make_shared<const PointCloud>(std::move(c)), v});
    values[k] = k == 0 ? truth[0] : truth[k] * test::random_pose(rng, 0.05, 0.2);
  }
  FactorGraph graph;
  const auto pairs = add_overlapping_pairs(graph, nodes, values, 0.025);
  EXPECT_EQ(pairs.size(), 45u);  // fully connected
  LevenbergMarquardt lm;
  const LMResult r = lm.optimize(graph, values, {0});
  EXPECT_LT(r.final_error, r.initial_error);
  for (int k = 1; k < 10; ++k) {
    EXPECT_LT(test::translation_error(values[k], truth[k]), 0.03) << k;
    EXPECT_LT(test::rotation_error_deg(values[k], truth[k]), 0.1) << k;
  }
  // The re-associated error at the last accepted point ends below where it started.
  ASSERT_FALSE(r.history.empty());
  EXPECT_LT(r.history.back().error, r.initial_error);
}

TEST(LevenbergMarquardt, NeverAcceptsACostIncrease) {
  // Pure pose graph: trial_error is the true cost, so the history must be monotone.
  PoseGraphProblem p = square_loop(RobustKernel::none(), false);
  for (int k = 1; k < 4; ++k) p.initial[k] = p.initial[k] * se3_exp((Vector6d() << 0.5, -0.4, 0.3, 2, 1, -1).finished());
  LevenbergMarquardt lm;
  const LMResult r = lm.optimize(p.graph, p.initial, {0});
  double previous = r.initial_error;
  for (const LMIteration& it : r.history) {
    EXPECT_LE(it.error, previous + 1e-12);
    previous = it.error;
  }
  EXPECT_LT(r.final_error, 1e-10);
}

class Kitti07 : public ::testing::Test {
 protected:
  void SetUp() override {
    GCMAP_REQUIRE_SHARED_DATA("kitti07_submaps");
    const std::string dir = test::shared_data() + "/kitti07_submaps";
    reference = read_trajectory(dir + "/graph.txt");
    for (int k = 0; k < 5; ++k) {
      nodes.push_back(make_scan_node(read_point_cloud(dir + "/00000" + std::to_string(k) + "/points.bin", BinFields::xyz), 1.0));
    }
  }
  Values solve(Values values) {
    FactorGraph graph;
    add_overlapping_pairs(graph, nodes, values, 0.025);
    LevenbergMarquardt lm;
    lm.optimize(graph, values, {0});
    return values;
  }
  Trajectory reference;
  std::vector<ScanNode> nodes;
};

TEST_F(Kitti07, PerturbedPosesComeBack) {
  Values start;
  for (int k = 0; k < 5; ++k) start[k] = reference.poses[k];
  const Values optimum = solve(start);
  // Our optimum vs the reference implementation's: measured up to 5.9 cm / 0.15 deg at cloud 4
  // (27 m from the fixed cloud 0), whatever the voxel size. The clouds do not pin graph.txt down
  // closer: pairwise, VGICP and kNN GICP agree on clouds 3-4 within 4 mm / 0.01 deg and both sit
  // 2.8 cm / 0.13 deg from it (and the reference's own test allows 15 cm / 0.86 deg).
  for (int k = 0; k < 5; ++k) {
    EXPECT_LT(test::translation_error(optimum.at(k), reference.poses[k]), 0.07) << k;
    EXPECT_LT(test::rotation_error_deg(optimum.at(k), reference.poses[k]), 0.2) << k;
  }
  std::mt19937_64 rng(2024);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int trial = 0; trial < 3; ++trial) {
    Values perturbed = start;
    for (int k = 1; k < 5; ++k) {
      Vector6d d;
      for (int a = 0; a < 3; ++a) d[a] = 0.1 * u(rng);
      for (int a = 3; a < 6; ++a) d[a] = 0.3 * u(rng);
      perturbed[k] = start[k] * se3_exp(d);
    }
    const Values result = solve(perturbed);
    for (int k = 0; k < 5; ++k) {
      EXPECT_LT(test::translation_error(result.at(k), optimum.at(k)), 0.03) << "trial " << trial << " pose " << k;
      EXPECT_LT(test::rotation_error_deg(result.at(k), optimum.at(k)), 0.1) << "trial " << trial << " pose " << k;
    }
  }
}

}  // namespace
}  // namespace gcmap
