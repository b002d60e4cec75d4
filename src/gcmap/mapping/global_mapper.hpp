#pragma once
// Global mapping (paper Section III-B): each new submap gets a matching-cost factor to every past
// submap it overlaps; LM, warm-started per insertion, re-linearizes every factor each iteration
// (global.relinearize: always, the paper) or only those whose poses moved (moved).
#include <memory>
#include <optional>
#include <vector>

#include "gcmap/core/timer.hpp"
#include "gcmap/graph/gnss_factor.hpp"
#include "gcmap/graph/gravity_factor.hpp"
#include "gcmap/graph/lazy_backend.hpp"
#include "gcmap/graph/levenberg_marquardt.hpp"
#include "gcmap/mapping/config.hpp"
#include "gcmap/mapping/factor_kind.hpp"
#include "gcmap/graph/gravity_window.hpp"
#include "gcmap/mapping/loop_detector.hpp"
#include "gcmap/mapping/submap.hpp"

namespace gcmap {

// One factor of the global graph and what is known of it.
struct GlobalFactor {
  FactorKind kind = FactorKind::matching_cost;
  int source = 0, target = 0;  // submaps
  double overlap = 0.0;        // at creation (matching_cost and se3)
  std::shared_ptr<Factor> factor;
};

// Information of a relative-pose factor that keeps a submap connected where nothing overlaps it.
Matrix6d odometry_factor_information();

// A factor's state at the current estimate.
struct FactorEvaluation {
  double error = 0.0;
  double weight = 1.0;  // robust-kernel weight (relative-pose factors)
};

// A GNSS fix placed on a submap: the antenna in the submap frame at the fix's stamp, and where the
// fix puts it in the local ENU frame.
struct GnssMeasurement {
  int submap = 0;
  size_t fix = 0;  // index in the input's fixes
  Eigen::Vector3d p_submap_antenna = Eigen::Vector3d::Zero(), p_enu = Eigen::Vector3d::Zero(), sigma = Eigen::Vector3d::Ones();
};

// The rigid transform turning `world` points onto `enu` points about the vertical only (yaw and a
// 3-D translation), weighted, with two passes that leave out points beyond
// max(4 x the median residual, 0.5 m). inliers (optional): per point, whether the last pass kept it.
Eigen::Isometry3d fit_yaw_translation(const std::vector<Eigen::Vector3d>& world, const std::vector<Eigen::Vector3d>& enu,
                                      const std::vector<double>& weights, std::vector<char>* inliers = nullptr);

// Of `kept` (overlaps of targets submaps[t.index]), the n with the largest overlap, `keep`'s always
// among them when there, in their order in `kept`; all of them when n <= 0.
std::vector<TargetOverlap> strongest_overlaps(std::vector<TargetOverlap> kept, const std::vector<int>& submaps, int keep, int n);

struct GlobalMappingStats {
  TimingStats factors, optimization;
  struct PerSubmap {
    int num_submaps, num_factors;
    double global_optimization_ms;
    int global_iterations;  // LM iterations of this insertion, over all its optimize calls
    // Where that time went (LMResult's split); factors linearized anew (relinearize: moved).
    double linearize_ms = 0.0, assemble_ms = 0.0, solve_ms = 0.0;
    size_t linearized = 0;
  };
  std::vector<PerSubmap> per_submap;
  double final_optimization_ms = 0.0;  // also one sample of optimization
  int final_iterations = 0;
  // Over all LM iterations (relinearize: moved); deferrals: moved factors left to a later iteration
  // by global.max_relinearizations.
  size_t factor_linearizations = 0, factor_reuses = 0, factor_deferrals = 0;
  LinearSolver linear_solver = LinearSolver::eigen;  // in use by the insertions' LM at the end
};

class GlobalMapper {
 public:
  // Of loop: whether explicit loops are on, exclude_recent and the loop constraint.
  GlobalMapper(const GlobalMappingConfig& config, const LoopConfig& loop, std::shared_ptr<LinearizationBackend> backend,
               const GnssConfig& gnss = {}, const ImuConfig& imu = {});

  // Inserts the next submap (ids in order), connects and optimizes it; `loops` (may be null) is
  // asked for an explicit loop in full mode.
  // gnss: the fixes placed on this submap. Until the fixes span gnss.align_distance they wait and
  // submap 0 is held fixed; then every pose is moved onto them by fit_yaw_translation (the world
  // becomes the local ENU frame), they become GnssPositionFactors, and no pose is held any more.
  // gravity: the accelerometer's window tied to this submap. The first levels the world about
  // submap 0's origin (its heading and position kept); each becomes a GravityFactor on the submap
  // and the accelerometer's bias (a variable of the graph, kAccelBiasKey), and submap 0 is held by
  // its position and heading only (until georeferenced: then by nothing).
  // gyro: the gyro's rotation from the previous submap's origin to this one's, a factor between them.
  void insert(Submap submap, LoopDetector* loops, std::vector<GnssMeasurement> gnss = {},
              std::optional<GravityWindow> gravity = std::nullopt, const std::optional<GyroRotation>& gyro = std::nullopt);
  // The final optimization, to a 1e-6 relative tolerance, of at most global.final_iterations
  // (or max_iterations when given; 0 skips it); on_iteration after each of its iterations.
  void optimize_final(std::optional<int> max_iterations = std::nullopt, const IterationCallback& on_iteration = {});
  // Insertions end their optimization early once *stop is true (LevenbergMarquardt::stop_on).
  void stop_on(const std::atomic<bool>* stop) { lm_.stop_on(stop); }

  const std::vector<Submap>& submaps() const { return submaps_; }
  const Eigen::Isometry3d& pose(int id) const { return values_.at(id); }
  const std::vector<GlobalFactor>& factors() const { return factors_; }
  // Error and weight of every factor at the current poses (in factors() order).
  std::vector<FactorEvaluation> evaluate_factors() const;
  const GlobalMappingStats& stats() const { return stats_; }
  // The poses are in the local ENU frame of the fixes.
  bool georeferenced() const { return georeferenced_; }
  const std::vector<std::shared_ptr<GnssPositionFactor>>& gnss_factors() const { return gnss_factors_; }
  const std::vector<GnssMeasurement>& gnss_measurements() const { return gnss_used_; }  // in gnss_factors() order
  size_t gnss_waiting() const { return gnss_pending_.size(); }
  // The world's z is gravity's (held there by the accelerometer).
  bool levelled() const { return !gravity_factors_.empty(); }
  const std::vector<std::shared_ptr<GravityFactor>>& gravity_factors() const { return gravity_factors_; }
  Eigen::Vector3d accel_bias() const;  // m/s^2, IMU frame; zero before the first window
  // The pose that carries the accelerometer's bias in the graph (its translation).
  const Eigen::Isometry3d& accel_bias_pose() const { return values_.at(kAccelBiasKey); }
  static constexpr int kAccelBiasKey = -1;
  // Forgets the IMU (found misplaced): its gravity and gyro factors; submap 0 is held again where it is.
  void drop_imu();

 private:
  void add_factor(GlobalFactor f);
  void take_gnss(std::vector<GnssMeasurement> gnss);
  bool try_georeference();
  void add_gnss_factor(const GnssMeasurement& m);
  void take_gravity(const GravityWindow& window);
  void level_world(const Eigen::Vector3d& up_world);
  std::set<int> fixed() const { return georeferenced_ || gauge_ ? std::set<int>{} : std::set<int>{0}; }
  // The factors not between submaps: GNSS fixes, gravity, and the hold on submap 0 while
  // levelled but not georeferenced.
  void add_unary(FactorGraph& g) const;
  FactorGraph graph() const;
  std::shared_ptr<LinearizationBackend> lm_backend() const;
  void count_linearizations();
  // Runs LM on `graph`, adding its iterations and time split to `into`.
  void optimize(const FactorGraph& graph, GlobalMappingStats::PerSubmap& into);
  // Matching-cost (or se3) factors from submap id to every past submap in [first, id) not yet
  // connected whose overlap reaches global.th_min; returns how many were added.
  int connect_overlapping(int id, int first);
  // The graph without matching-cost factors between submaps more than loop.exclude_recent apart
  // (kept where a submap has nothing else).
  FactorGraph without_revisit_factors() const;

  GlobalMappingConfig config_;
  LoopConfig loop_;
  GnssConfig gnss_;
  bool georeferenced_ = false;
  std::vector<GnssMeasurement> gnss_pending_, gnss_used_;
  std::vector<std::shared_ptr<GnssPositionFactor>> gnss_factors_;
  ImuConfig imu_;
  std::vector<std::shared_ptr<GravityFactor>> gravity_factors_;
  std::vector<std::shared_ptr<RelativePoseFactor>> gyro_factors_;
  std::shared_ptr<AccelBiasPriorFactor> accel_bias_prior_;
  std::shared_ptr<HeadingPositionFactor> gauge_;
  std::shared_ptr<LinearizationBackend> backend_;
  std::shared_ptr<LazyBackend> lazy_;  // between LM and backend_ when global.relinearize is moved
  std::vector<Submap> submaps_;
  std::vector<GlobalFactor> factors_;
  std::vector<char> connected_;  // per past submap: has a factor from the submap being inserted
  Values values_;
  LevenbergMarquardt lm_;
  GlobalMappingStats stats_;
};

}  // namespace gcmap
