// The odometry's model: which frames become its keyframes.
#include "gcmap/core/preprocess.hpp"
#include "gcmap/core/se3.hpp"
#include "gcmap/odometry/odometry.hpp"
#include "gcmap/sim/synthetic.hpp"
#include "test_util.hpp"

namespace gcmap {
namespace {

std::shared_ptr<const PointCloud> scene_cloud(uint64_t seed) {
  PointCloud c = voxel_downsample(make_structured_scene(5000, seed), 0.25);
  estimate_covariances(c);
  return std::make_shared<const PointCloud>(std::move(c));
}

// A frame turned 20 deg from the last keyframe (past keyframe_angle_deg) joins the model when it
// was registered or the IMU placed it; one the constant-velocity prediction placed (its
// registration refused) never does: where the prediction erred, every later registration would.
TEST(Odometry, AFramePlacedByThePredictionNeverJoinsTheModel) {
  const Eigen::Isometry3d turned = se3_exp((Vector6d() << 0.0, 0.0, 20.0 * M_PI / 180.0, 0.3, 0.0, 0.0).finished());
  const auto joins = [&](bool failed, bool imu_placed) {
    OdometryConfig config;
    config.model_keyframes = 1;  // full after the first frame
    Odometry odometry(config);
    odometry.accept(scene_cloud(1), Eigen::Isometry3d::Identity(), 0.0);
    const auto frame = scene_cloud(2);
    odometry.accept(frame, turned, 0.1, failed, {}, imu_placed);
    return odometry.revise_keyframe(*frame, frame, turned);  // true only for a keyframe
  };
  EXPECT_TRUE(joins(false, false)) << "registered";
  EXPECT_TRUE(joins(true, true)) << "placed by the IMU's state";
  EXPECT_FALSE(joins(true, false)) << "placed by the constant-velocity prediction";
}

}  // namespace
}  // namespace gcmap
