// The trajectory's rotations refined with the gyro (graph/rotation_smoother.hpp): noisy frames get
// closer to the truth, frames already better than the gyro are left alone, a gap splits the chain.
#include <cmath>
#include <random>

#include "gcmap/graph/rotation_smoother.hpp"
#include "test_util.hpp"

namespace gcmap {
namespace {

constexpr double kDeg = M_PI / 180.0;

// 30 s at 10 Hz of a walker's head: a slow turn with a gait's pitch and roll nod at 1.8 Hz.
std::vector<Eigen::Isometry3d> walk(int n) {
  std::vector<Eigen::Isometry3d> truth(n, Eigen::Isometry3d::Identity());
  for (int k = 0; k < n; ++k) {
    const double t = 0.1 * k;
    truth[k].linear() = so3_exp(Eigen::Vector3d(3 * kDeg * std::sin(11.3 * t), 4 * kDeg * std::cos(11.3 * t), 0.3 * t));
    truth[k].translation() = Eigen::Vector3d(1.2 * t, 0.1 * std::sin(t), 0.05 * std::sin(11.3 * t));
  }
  return truth;
}

Eigen::Vector3d normal3(std::mt19937_64& rng, double sigma) {
  std::normal_distribution<double> g(0.0, sigma);
  return {g(rng), g(rng), g(rng)};
}

struct Case {
  std::vector<Eigen::Isometry3d> truth, given;
  std::vector<std::optional<GyroRotation>> gyro;
};

// The frames' rotations off by frame_sigma (deg, white, per axis), the gyro by gyro_sigma per step.
Case make_case(double frame_sigma, double gyro_sigma, int n = 300) {
  std::mt19937_64 rng(7);
  Case c{walk(n), {}, std::vector<std::optional<GyroRotation>>(n)};
  for (int k = 0; k < n; ++k) {
    Eigen::Isometry3d T = c.truth[k];
    T.linear() = T.linear() * so3_exp(normal3(rng, frame_sigma * kDeg));
    c.given.push_back(T);
    if (k == 0) continue;
    const Eigen::Matrix3d R = c.truth[k - 1].linear().transpose() * c.truth[k].linear();
    c.gyro[k] = GyroRotation{R * so3_exp(normal3(rng, gyro_sigma * kDeg)), std::pow(gyro_sigma * kDeg, 2)};
  }
  return c;
}

double rms_error_deg(const std::vector<Eigen::Isometry3d>& truth, const std::vector<Eigen::Isometry3d>& est) {
  double sum = 0.0;
  for (size_t k = 0; k < truth.size(); ++k) sum += std::pow(test::rotation_error_deg(truth[k], est[k]), 2);
  return std::sqrt(sum / truth.size());
}

TEST(RotationSmoother, NoisyFramesComeCloserToTheTruthThroughTheGyro) {
  Case c = make_case(0.2, 0.03);
  c.gyro[150].reset();  // a gap: the two halves are smoothed apart
  std::vector<Eigen::Isometry3d> poses = c.given;
  const RotationSmoothing s = smooth_rotations(poses, c.gyro);
  ASSERT_TRUE(s.applied);
  // White frames: what the gyro cannot explain over five frames is the frames' own noise.
  EXPECT_NEAR(s.frame_noise_deg, 0.2, 0.04);
  EXPECT_NEAR(s.gyro_noise_deg, 0.03, 1e-9);
  const double before = rms_error_deg(c.truth, c.given), after = rms_error_deg(c.truth, poses);
  std::printf("rotation error %.3f -> %.3f deg RMS\n", before, after);
  EXPECT_LT(after, 0.5 * before);
  for (size_t k = 0; k < poses.size(); ++k) {
    ASSERT_EQ(poses[k].translation(), c.given[k].translation()) << k;
    EXPECT_LT(test::rotation_error_deg(poses[k], c.truth[k]), 0.3) << k;  // the given frames reach 0.7
  }
}

TEST(RotationSmoother, FramesBetterThanTheGyroAreLeftAlone) {
  Case c = make_case(0.005, 0.03);
  std::vector<Eigen::Isometry3d> poses = c.given;
  const RotationSmoothing s = smooth_rotations(poses, c.gyro);
  EXPECT_FALSE(s.applied);
  EXPECT_LT(s.frame_noise_deg, 0.03);
  for (size_t k = 0; k < poses.size(); ++k) ASSERT_TRUE(poses[k].isApprox(c.given[k], 0.0)) << k;
}

TEST(RotationSmoother, TooFewWindowsChangeNothing) {
  Case c = make_case(0.2, 0.03, 60);  // 11 windows of five frames
  std::vector<Eigen::Isometry3d> poses = c.given;
  EXPECT_FALSE(smooth_rotations(poses, c.gyro).applied);
  for (size_t k = 0; k < poses.size(); ++k) ASSERT_TRUE(poses[k].isApprox(c.given[k], 0.0)) << k;
}

}  // namespace
}  // namespace gcmap
