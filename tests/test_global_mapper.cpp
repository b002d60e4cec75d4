// Global mapping: how many factors a new submap gets.
#include <set>

#include "gcmap/core/preprocess.hpp"
#include "gcmap/core/se3.hpp"
#include "gcmap/graph/matching_graph.hpp"
#include "gcmap/mapping/global_mapper.hpp"
#include "gcmap/sim/synthetic.hpp"
#include "test_util.hpp"

namespace gcmap {
namespace {

// Submap k of one keyframe: a scan node (its cloud is also its factors' source) at T_odom.
Submap one_scan_submap(int k, const ScanNode& node, const Eigen::Isometry3d& T_odom) {
  Submap s;
  s.id = k;
  s.keyframes = {k};
  s.T_submap_keyframe = {Eigen::Isometry3d::Identity()};
  s.T_odom = T_odom;
  s.cloud = s.factor_source = node.cloud;
  s.voxels = node.voxels;
  return s;
}

// Every submap inserted, then the final optimization.
GlobalMapper map_all(const std::vector<Submap>& submaps, const GlobalMappingConfig& config) {
  GlobalMapper mapper(config, LoopConfig{}, std::make_shared<CpuBackend>());
  for (const Submap& s : submaps) mapper.insert(s, nullptr);
  mapper.optimize_final();
  return mapper;
}

// Submaps 2 m apart along one scene, each sampling it anew, so that each overlaps most of those
// before it, less the further back; their odometry drifts 1 cm and 0.1 deg per submap.
struct Corridor {
  std::vector<Eigen::Isometry3d> truth;
  std::vector<Submap> submaps;

  explicit Corridor(int n) {
    const Eigen::Isometry3d drift = se3_exp((Vector6d() << 0.0, 0.0, 0.1 * M_PI / 180.0, 0.01, 0.0, 0.0).finished());
    Eigen::Isometry3d odom = Eigen::Isometry3d::Identity();
    for (int k = 0; k < n; ++k) {
      truth.push_back(Eigen::Isometry3d(Eigen::Translation3d(2.0 * k, 0.0, 0.0)));
      if (k > 0) odom = odom * truth[k - 1].inverse() * truth[k] * drift;
      const PointCloud scene = voxel_downsample(make_structured_scene(20000, 500 + k), 0.25);
      submaps.push_back(one_scan_submap(k, make_scan_node(transformed(scene, truth[k].inverse()), 0.5), odom));
    }
  }

  GlobalMapper map(int max_new_factors) const {
    GlobalMappingConfig config;
    config.max_new_factors = max_new_factors;
    return map_all(submaps, config);
  }
};

// global.robust_width reaches every matching cost, and the errors reported for graph.json are the
// costs the factors optimized (Cauchy's), not the plain squares.
TEST(GlobalMapper, ARobustWidthReachesTheFactorsAndTheirReportedErrors) {
  const Corridor corridor(4);
  GlobalMappingConfig config;
  config.robust_width = 0.25;
  const GlobalMapper mapper = map_all(corridor.submaps, config);
  const std::vector<FactorEvaluation> evaluation = mapper.evaluate_factors();
  int checked = 0;
  for (size_t f = 0; f < mapper.factors().size(); ++f) {
    auto* m = dynamic_cast<MatchingCostFactor*>(mapper.factors()[f].factor.get());
    if (!m) continue;
    EXPECT_EQ(m->robust_width(), 0.25f);
    const Eigen::Isometry3d* poses[2] = {&mapper.pose(m->keys()[0]), &mapper.pose(m->keys()[1])};
    FactorLinearization lin;
    m->linearize(poses, lin);
    EXPECT_NEAR(evaluation[f].error, lin.error, 1e-9 * lin.error) << f;
    ++checked;
  }
  EXPECT_GE(checked, 3);
}

TEST(GlobalMapper, StrongestOverlapsAreThoseOverlappingMostAndThePredecessor) {
  const std::vector<int> submaps = {3, 5, 6, 8, 9};
  const std::vector<TargetOverlap> kept = {{0, 0.4}, {1, 0.1}, {2, 0.3}, {4, 0.05}};  // submap 8 below th_min
  const auto indices = [](const std::vector<TargetOverlap>& t) {
    std::vector<int> out;
    for (const TargetOverlap& o : t) out.push_back(o.index);
    return out;
  };
  EXPECT_EQ(indices(strongest_overlaps(kept, submaps, 9, 2)), std::vector<int>({0, 4})) << "the predecessor, then the most";
  EXPECT_EQ(indices(strongest_overlaps(kept, submaps, 7, 2)), std::vector<int>({0, 2})) << "no predecessor among them";
  EXPECT_EQ(indices(strongest_overlaps(kept, submaps, 9, 3)), std::vector<int>({0, 2, 4}));
  EXPECT_EQ(indices(strongest_overlaps(kept, submaps, 9, 4)), indices(kept));
  EXPECT_EQ(indices(strongest_overlaps(kept, submaps, 9, 0)), indices(kept)) << "0: no limit";
}

// Per submap, the targets of its factors.
std::vector<std::set<int>> targets_of(const GlobalMapper& mapper) {
  std::vector<std::set<int>> out(mapper.submaps().size());
  for (const GlobalFactor& f : mapper.factors()) out[f.source].insert(f.target);
  return out;
}

TEST(GlobalMapper, ANewSubmapGetsAtMostMaxNewFactorsAndStillUndoesTheDrift) {
  const Corridor corridor(8);
  const GlobalMapper every = corridor.map(0), capped = corridor.map(3);
  const auto all = targets_of(every), kept = targets_of(capped);
  EXPECT_GT(all.back().size(), 3u) << "the last submap overlaps more than three before it";
  for (size_t id = 1; id < all.size(); ++id) {
    EXPECT_EQ(kept[id].size(), std::min<size_t>(all[id].size(), 3)) << id;
    EXPECT_TRUE(kept[id].count(static_cast<int>(id) - 1)) << id;
  }
  // The odometry's drift reaches 0.7 deg and 0.1 m at the last submap.
  for (const GlobalMapper* mapper : {&every, &capped})
    for (size_t id = 1; id < corridor.truth.size(); ++id) {
      const Eigen::Isometry3d T_0_id = mapper->pose(0).inverse() * mapper->pose(static_cast<int>(id));
      EXPECT_LT(test::translation_error(T_0_id, corridor.truth[id]), 0.03) << id;
      EXPECT_LT(test::rotation_error_deg(T_0_id, corridor.truth[id]), 0.05) << id;
    }
}

// A straight tunnel (make_tunnel_scan) seen to 25 m from each submap, submaps 8 m apart; the
// odometry makes each step 8.4 m, as one sliding along a tunnel does.
struct Tunnel {
  std::vector<Submap> submaps;

  explicit Tunnel(int n) {
    for (int k = 0; k < n; ++k) {
      const ScanNode node = make_scan_node(voxel_downsample(make_tunnel_scan(40000, 40 + k, 25.0), 0.25), 0.5);
      submaps.push_back(one_scan_submap(k, node, Eigen::Isometry3d(Eigen::Translation3d(8.4 * k, 0.0, 0.0))));
    }
  }

  GlobalMapper map(double min_conditioning) const {
    GlobalMappingConfig config;
    config.min_conditioning = min_conditioning;
    return map_all(submaps, config);
  }
};

// Where the matching costs cannot see along a tunnel, what they tell along it is noise: they
// stretched the odometry's 42 m further. Blind along it, the graph stays near what the odometry says.
TEST(GlobalMapper, ATunnelKeepsTheOdometrysLengthWhereTheMatchingCostsCannotSeeAlongIt) {
  const Tunnel tunnel(6);
  const auto length = [&](const GlobalMapper& m) {
    return (m.pose(0).inverse() * m.pose(static_cast<int>(tunnel.submaps.size()) - 1)).translation().x();
  };
  const GlobalMapper blind = tunnel.map(0.03), seeing = tunnel.map(0.0);
  EXPECT_NEAR(length(blind), 42.0, 0.12);  // measured 42.08
  EXPECT_GT(length(seeing), 42.2) << "without it (the case this guards against); measured 42.30";
}

}  // namespace
}  // namespace gcmap
