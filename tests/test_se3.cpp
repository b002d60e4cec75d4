#include "gcmap/core/se3.hpp"
#include "test_util.hpp"

namespace gcmap {
namespace {

TEST(SE3, ExpLogRoundTrip) {
  std::mt19937_64 rng(1);
  for (int i = 0; i < 200; ++i) {
    const Eigen::Isometry3d T = test::random_pose(rng, i < 100 ? 1.0 : 3.1, 10.0);
    const Eigen::Isometry3d back = se3_exp(se3_log(T));
    EXPECT_LT((back.matrix() - T.matrix()).norm(), 1e-9) << "sample " << i;
  }
  // Tiny and near-pi rotations take special branches.
  Vector6d xi;
  xi << 1e-9, -2e-9, 3e-9, 1.0, 2.0, 3.0;
  EXPECT_LT((se3_log(se3_exp(xi)) - xi).norm(), 1e-12);
  xi << M_PI - 1e-7, 0, 0, 0.5, 0, 0;
  EXPECT_LT((se3_exp(se3_log(se3_exp(xi))).matrix() - se3_exp(xi).matrix()).norm(), 1e-6);
}

TEST(SE3, AdjointMovesPerturbations) {
  std::mt19937_64 rng(2);
  const Eigen::Isometry3d T = test::random_pose(rng, 1.0, 5.0);
  Vector6d xi;
  xi << 0.1, -0.2, 0.3, 0.4, -0.5, 0.6;
  const Eigen::Isometry3d lhs = T * se3_exp(xi) * T.inverse();
  const Eigen::Isometry3d rhs = se3_exp(adjoint(T) * xi);
  EXPECT_LT((lhs.matrix() - rhs.matrix()).norm(), 1e-12);
}

TEST(SE3, RightJacobianInverseMatchesNumeric) {
  std::mt19937_64 rng(3);
  for (int s = 0; s < 20; ++s) {
    Vector6d xi = se3_log(test::random_pose(rng, s < 10 ? 1.2 : 1e-5, 3.0));
    const Matrix6d analytic = se3_right_jacobian_inverse(xi);
    Matrix6d numeric;
    const double h = 1e-6;
    for (int k = 0; k < 6; ++k) {
      Vector6d d = Vector6d::Zero();
      d[k] = h;
      numeric.col(k) = (se3_log(se3_exp(xi) * se3_exp(d)) - se3_log(se3_exp(xi) * se3_exp(-d))) / (2 * h);
    }
    EXPECT_LT((analytic - numeric).norm(), 1e-6) << "sample " << s << "\n" << analytic << "\n\n" << numeric;
  }
}

TEST(SE3, QuaternionPoseRoundTrip) {
  const double v[7] = {1, 2, 3, 0.1, 0.2, 0.3, 0.9};
  double out[7];
  pose_to_xyz_quat(pose_from_xyz_quat(v), out);
  const double n = std::sqrt(0.01 + 0.04 + 0.09 + 0.81);
  for (int k = 0; k < 3; ++k) EXPECT_DOUBLE_EQ(out[k], v[k]);
  for (int k = 3; k < 7; ++k) EXPECT_NEAR(out[k], v[k] / n, 1e-12);
}

}  // namespace
}  // namespace gcmap
