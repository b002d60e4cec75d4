// Local mapping: the gyro's rotations between a submap's keyframes.
#include "gcmap/core/preprocess.hpp"
#include "gcmap/core/se3.hpp"
#include "gcmap/mapping/submap_builder.hpp"
#include "gcmap/sim/synthetic.hpp"
#include "test_util.hpp"

namespace gcmap {
namespace {

// Four frames through one scene, each with its own sampling; frame 2 is unusable (no cloud). The
// gyro's rotation since the previous frame is the truth's, but frame 2's is turned by
// `frame2_turn` (absent: none given) and frame 3's by `frame3_turn`. Returns the submap's rotation
// from keyframe 1 to keyframe 3 against the truth's (deg) and counts the gyro factors.
double keyframe_rotation_error_deg(const std::optional<Eigen::Vector3d>& frame2_turn, const Eigen::Vector3d& frame3_turn,
                                   size_t* gyro_factors) {
  LocalMappingConfig local;
  local.th_max = 1.0;  // every usable frame is a keyframe: each sees the whole scene
  SubmapBuilder builder(local, GlobalMappingConfig{}, LoopConfig{}, std::make_shared<CpuBackend>());
  std::vector<Eigen::Isometry3d> truth;
  for (int k = 0; k < 4; ++k) truth.push_back(se3_exp((Vector6d() << 0.0, 0.0, 0.05 * k, 1.0 * k, 0.2 * k, 0.0).finished()));
  for (int k = 0; k < 4; ++k) {
    std::shared_ptr<const PointCloud> cloud;
    if (k != 2) {
      PointCloud c = transformed(voxel_downsample(make_structured_scene(20000, 300 + k), 0.25), truth[k].inverse());
      estimate_covariances(c);
      cloud = std::make_shared<const PointCloud>(std::move(c));
    }
    std::optional<GyroRotation> gyro;
    if (k > 0 && (k != 2 || frame2_turn)) {
      const Eigen::Vector3d turn = k == 2 ? *frame2_turn : k == 3 ? frame3_turn : Eigen::Vector3d::Zero();
      gyro = GyroRotation{(truth[k - 1].inverse() * truth[k]).linear() * so3_exp(turn), 1e-12};
    }
    const auto r = builder.add_frame(k, cloud, truth[k], std::nullopt, gyro);
    EXPECT_EQ(r.status, k == 2 ? FrameStatus::unusable : FrameStatus::keyframe) << k;
  }
  const std::optional<Submap> s = builder.close();
  EXPECT_TRUE(s && s->keyframes == std::vector<int>({0, 1, 3}));
  *gyro_factors = builder.stats().gyro_factors;
  if (!s || s->keyframes.size() != 3) return NAN;
  const Eigen::Matrix3d R_1_3 = (s->T_submap_keyframe[1].inverse() * s->T_submap_keyframe[2]).linear();
  const Eigen::Matrix3d truth_1_3 = (truth[1].inverse() * truth[3]).linear();
  return so3_log(truth_1_3.transpose() * R_1_3).norm() * 180.0 / M_PI;
}

TEST(SubmapBuilder, KeyframesTakeTheGyrosRotationThroughTheFramesBetweenThem) {
  const double half_deg = 0.5 * M_PI / 180.0;
  size_t factors = 0;
  // The gyro's rotation from keyframe 1 to 3 runs through the unusable frame 2, whose turn it
  // carries: the keyframes take it, against the scene's own.
  EXPECT_NEAR(keyframe_rotation_error_deg(Eigen::Vector3d(0.0, half_deg, 0.0), Eigen::Vector3d::Zero(), &factors), 0.5, 0.01);
  EXPECT_EQ(factors, 2u);
  // Frame 2 without a gyro rotation: nothing ties keyframe 3 to keyframe 1 but the matching costs,
  // however frame 3's rotation is turned.
  EXPECT_LT(keyframe_rotation_error_deg(std::nullopt, Eigen::Vector3d(0.0, half_deg, 0.0), &factors), 0.05);
  EXPECT_EQ(factors, 1u);
}

}  // namespace
}  // namespace gcmap
