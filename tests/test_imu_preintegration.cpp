#include <random>

#include "gcmap/core/error.hpp"
#include "gcmap/graph/imu_factors.hpp"
#include "gcmap/graph/imu_preintegration.hpp"
#include "imu_test_util.hpp"
#include "test_util.hpp"

namespace gcmap {
namespace {

ImuBias random_bias(std::mt19937_64& rng, double gyro, double accel) {
  std::normal_distribution<double> n(0.0, 1.0);
  ImuBias b;
  for (int k = 0; k < 3; ++k) b.gyro[k] = gyro * n(rng), b.accel[k] = accel * n(rng);
  return b;
}

NavState random_state(std::mt19937_64& rng) {
  NavState s;
  s.T_world_imu = test::random_pose(rng, 2.0, 10.0);
  std::normal_distribution<double> n(0.0, 1.0);
  s.velocity = Eigen::Vector3d(n(rng), n(rng), n(rng)) * 3.0;
  s.bias = random_bias(rng, 0.05, 0.3);
  return s;
}

// Varied, bounded measurements over 0.5 s at 200 Hz.
ImuPreintegration random_preintegration(std::mt19937_64& rng, const ImuBias& bias_lin, const ImuNoise& noise = {}) {
  ImuPreintegration pre(bias_lin, noise);
  std::normal_distribution<double> n(0.0, 1.0);
  for (int k = 0; k < 100; ++k) {
    const Eigen::Vector3d w(0.5 * n(rng), 0.5 * n(rng), 1.0 + 0.5 * n(rng));
    const Eigen::Vector3d a(2.0 * n(rng), 2.0 * n(rng), 9.8 + n(rng));
    pre.integrate(w, a, 0.005);
  }
  return pre;
}

TEST(ImuPreintegration, NoiseFreeSamplesReproduceTheTrajectory) {
  const test::SmoothTrajectory traj;
  for (const double rate : {1000.0, 2000.0}) {
    ImuPreintegration pre;
    pre.integrate(traj.samples(0.0, 1.0, rate), 0.0, 1.0);
    EXPECT_NEAR(pre.dt(), 1.0, 1e-12);
    const NavState end = pre.predict(traj.state(0.0));
    const NavState truth = traj.state(1.0);
    // The trapezoid steps are second order: 1 kHz leaves 3e-7 m, 2 kHz a quarter of that.
    EXPECT_LT((end.T_world_imu.translation() - truth.T_world_imu.translation()).norm(), 1e-6) << rate << " Hz";
    EXPECT_LT(so3_log(end.T_world_imu.linear().transpose() * truth.T_world_imu.linear()).norm(), 1e-6) << rate << " Hz";
    EXPECT_LT((end.velocity - truth.velocity).norm(), 1e-6) << rate << " Hz";
  }
}

TEST(ImuPreintegration, IntegratesBetweenSampleStamps) {
  // An interval that starts and ends between samples: the signal is interpolated at its ends.
  const test::SmoothTrajectory traj;
  ImuPreintegration pre;
  pre.integrate(traj.samples(0.0, 1.0, 2000.0), 0.10013, 0.80071);
  const NavState end = pre.predict(traj.state(0.10013));
  EXPECT_LT((end.T_world_imu.translation() - traj.position(0.80071)).norm(), 1e-6);
  EXPECT_THROW(pre.integrate(traj.samples(0.0, 1.0, 100.0), 0.5, 1.2), Error);
}

TEST(ImuPreintegration, BiasJacobiansMatchReintegration) {
  std::mt19937_64 rng(3);
  const ImuBias b0 = random_bias(rng, 0.02, 0.2);
  std::mt19937_64 measurements(4);
  const ImuPreintegration base = random_preintegration(measurements, b0);
  const double h = 1e-6;
  for (int k = 0; k < 6; ++k) {
    ImuBias b = b0;
    (k < 3 ? b.gyro[k] : b.accel[k - 3]) += h;
    std::mt19937_64 same(4);
    const ImuPreintegration moved = random_preintegration(same, b);
    const Eigen::Vector3d dR = so3_log(base.delta_R().transpose() * moved.delta_R()) / h;
    const Eigen::Vector3d dv = (moved.delta_v() - base.delta_v()) / h, dp = (moved.delta_p() - base.delta_p()) / h;
    const Eigen::Vector3d JR = k < 3 ? Eigen::Vector3d(base.dR_dbg().col(k)) : Eigen::Vector3d::Zero();
    const Eigen::Vector3d Jv = k < 3 ? base.dv_dbg().col(k) : base.dv_dba().col(k - 3);
    const Eigen::Vector3d Jp = k < 3 ? base.dp_dbg().col(k) : base.dp_dba().col(k - 3);
    EXPECT_LT((dR - JR).norm(), 1e-4 * std::max(1.0, JR.norm())) << "bias component " << k;
    EXPECT_LT((dv - Jv).norm(), 1e-4 * std::max(1.0, Jv.norm())) << "bias component " << k;
    EXPECT_LT((dp - Jp).norm(), 1e-4 * std::max(1.0, Jp.norm())) << "bias component " << k;
  }
  // The first-order correction to a bias 0.01 rad/s, 0.1 m/s^2 away is better than not correcting
  // by far (its error is second order in the bias change).
  ImuBias b = b0;
  b.gyro += Eigen::Vector3d(0.01, -0.01, 0.005), b.accel += Eigen::Vector3d(0.1, 0.05, -0.1);
  std::mt19937_64 same(4);
  const ImuPreintegration re = random_preintegration(same, b);
  const double corrected = (base.corrected_delta_p(b) - re.delta_p()).norm();
  const double uncorrected = (base.delta_p() - re.delta_p()).norm();
  EXPECT_LT(corrected, 1e-2 * uncorrected);
  EXPECT_LT(so3_log(base.corrected_delta_R(b).transpose() * re.delta_R()).norm(),
            1e-2 * so3_log(base.delta_R().transpose() * re.delta_R()).norm());
  EXPECT_LT((base.corrected_delta_v(b) - re.delta_v()).norm(), 1e-2 * (base.delta_v() - re.delta_v()).norm());
}

TEST(ImuPreintegration, CovarianceMatchesMonteCarlo) {
  ImuNoise noise;
  noise.gyro_noise = 0.01, noise.accel_noise = 0.1;
  const double dt = 0.01;
  const int steps = 50, runs = 3000;
  std::mt19937_64 rng(5);
  std::normal_distribution<double> n(0.0, 1.0);
  std::vector<Eigen::Vector3d> w(steps), a(steps);
  for (int k = 0; k < steps; ++k) w[k] = Eigen::Vector3d(0.3, -0.2, 0.8) * std::sin(0.1 * k), a[k] = {1.0, 0.5, 9.8};
  ImuPreintegration clean({}, noise);
  for (int k = 0; k < steps; ++k) clean.integrate(w[k], a[k], dt);
  Matrix9d sample = Matrix9d::Zero();
  const double sg = noise.gyro_noise / std::sqrt(dt), sa = noise.accel_noise / std::sqrt(dt);
  for (int r = 0; r < runs; ++r) {
    ImuPreintegration noisy({}, ImuNoise{0.0, 0.0, 0.0, 0.0});
    for (int k = 0; k < steps; ++k)
      noisy.integrate(w[k] + sg * Eigen::Vector3d(n(rng), n(rng), n(rng)), a[k] + sa * Eigen::Vector3d(n(rng), n(rng), n(rng)),
                      dt);
    Vector9d e;
    e << so3_log(clean.delta_R().transpose() * noisy.delta_R()), noisy.delta_v() - clean.delta_v(),
        noisy.delta_p() - clean.delta_p();
    sample += e * e.transpose() / runs;
  }
  const Matrix9d& cov = clean.covariance();
  for (int i = 0; i < 9; ++i) EXPECT_NEAR(sample(i, i), cov(i, i), 0.15 * cov(i, i)) << "diagonal " << i;
  EXPECT_LT((sample - cov).norm(), 0.15 * cov.norm());
}

// Central differences of a factor's whitened residual over the 15 tangent directions of one state.
Eigen::MatrixXd numeric_jacobian(const NavFactor& f, std::vector<NavState> states, int which) {
  const auto residual = [&](const std::vector<NavState>& s) {
    const NavState* ptr[2] = {&s[0], s.size() > 1 ? &s[1] : nullptr};
    return f.linearize(ptr).r;
  };
  const double h = 1e-6;
  Eigen::MatrixXd J(residual(states).size(), 15);
  for (int d = 0; d < 15; ++d) {
    std::vector<NavState> plus = states, minus = states;
    plus[which] = states[which].retract(Vector15d::Unit(d) * h);
    minus[which] = states[which].retract(-Vector15d::Unit(d) * h);
    J.col(d) = (residual(plus) - residual(minus)) / (2 * h);
  }
  return J;
}

void expect_jacobians_match(const NavFactor& f, const std::vector<NavState>& states, const std::string& what) {
  const NavState* ptr[2] = {&states[0], states.size() > 1 ? &states[1] : nullptr};
  const NavLinearization lin = f.linearize(ptr);
  for (int k = 0; k < f.num_keys(); ++k) {
    const Eigen::MatrixXd numeric = numeric_jacobian(f, states, k);
    const double scale = std::max(1.0, numeric.cwiseAbs().maxCoeff());
    EXPECT_LT((lin.J[k] - numeric).cwiseAbs().maxCoeff(), 1e-5 * scale) << what << ", state " << k << "\nanalytic\n"
                                                                        << lin.J[k] << "\nnumeric\n"
                                                                        << numeric;
  }
}

TEST(ImuFactor, JacobiansMatchNumericDifferentiation) {
  std::mt19937_64 rng(6);
  for (int trial = 0; trial < 10; ++trial) {
    const ImuPreintegration pre = random_preintegration(rng, random_bias(rng, 0.02, 0.2));
    const ImuFactor f(0, 1, pre);
    const std::vector<NavState> states{random_state(rng), random_state(rng)};
    expect_jacobians_match(f, states, "IMU factor, trial " + std::to_string(trial));
    expect_jacobians_match(BiasRandomWalkFactor(0, 1, 0.5, ImuNoise{}), states, "bias walk");
    Matrix15d info = Matrix15d::Identity();
    info(0, 3) = info(3, 0) = 0.3;
    expect_jacobians_match(NavPriorFactor(0, random_state(rng), info), {states[0]}, "prior");
    Matrix6d pose_info = 4.0 * Matrix6d::Identity();
    pose_info(1, 4) = pose_info(4, 1) = 1.0;
    const Eigen::Isometry3d T_imu_lidar = test::random_pose(rng, 0.5, 0.3);
    const Eigen::Isometry3d measured = states[0].T_world_imu * T_imu_lidar * test::random_pose(rng, 0.3, 0.5);
    expect_jacobians_match(LidarPoseFactor(0, measured, pose_info, T_imu_lidar), {states[0]}, "LiDAR pose");
  }
}

TEST(ImuFactor, GravityJacobianMatchesNumericDifferentiation) {
  std::mt19937_64 rng(7);
  for (int trial = 0; trial < 5; ++trial) {
    ImuFactor f(0, 1, random_preintegration(rng, random_bias(rng, 0.02, 0.2)));
    const std::vector<NavState> states{random_state(rng), random_state(rng)};
    const NavState* ptr[2] = {&states[0], &states[1]};
    const Eigen::Vector3d g(0.3, -0.2, -9.8);
    Eigen::Matrix<double, 9, 3> numeric;
    for (int d = 0; d < 3; ++d) {
      f.set_gravity(g + 1e-6 * Eigen::Vector3d::Unit(d));
      const Eigen::VectorXd plus = f.linearize(ptr).r;
      f.set_gravity(g - 1e-6 * Eigen::Vector3d::Unit(d));
      numeric.col(d) = (plus - f.linearize(ptr).r) / 2e-6;
    }
    const Eigen::Matrix<double, 9, 3> analytic = f.gravity_jacobian(states[0]);
    EXPECT_LT((analytic - numeric).cwiseAbs().maxCoeff(), 1e-5 * std::max(1.0, numeric.cwiseAbs().maxCoeff())) << trial;
    EXPECT_GT(analytic.cwiseAbs().maxCoeff(), 1e-3) << "gravity enters the velocity and position rows";
  }
}

TEST(ImuFactor, ZeroAtTheTruth) {
  const test::SmoothTrajectory traj;
  const ImuBias bias{{0.01, -0.02, 0.005}, {0.1, -0.05, 0.2}};
  ImuPreintegration pre(bias);
  pre.integrate(traj.samples(0.0, 1.0, 2000.0, bias), 0.2, 0.7);
  const ImuFactor f(0, 1, pre);
  const Vector9d r = f.residual(traj.state(0.2, bias), traj.state(0.7, bias));
  EXPECT_LT(r.norm(), 1e-6);
  // A velocity 1 cm/s off shows.
  NavState off = traj.state(0.7, bias);
  off.velocity.x() += 0.01;
  EXPECT_NEAR(f.residual(traj.state(0.2, bias), off).segment<3>(3).norm(), 0.01, 1e-5);
}

TEST(ImuFactor, LevenbergMarquardtRecoversVelocitiesAndBiases) {
  // Five states 0.25 s apart whose poses are known (as LiDAR odometry gives them); velocities and
  // biases start at zero and come from the IMU alone.
  const test::SmoothTrajectory traj;
  const ImuBias bias{{0.01, -0.02, 0.015}, {0.15, -0.1, 0.2}};
  const std::vector<ImuSample> samples = traj.samples(0.0, 1.0, 2000.0, bias);
  const int n = 5;
  std::vector<NavState> states(n);
  std::mt19937_64 rng(7);
  for (int k = 0; k < n; ++k) { states[k].T_world_imu = traj.state(0.25 * k).T_world_imu * test::random_pose(rng, 0.01, 0.05); }
  Matrix15d info = Matrix15d::Zero();
  info.topLeftCorner<6, 6>() = 1e8 * Matrix6d::Identity();
  ImuNoise noise;
  // Twice: the second pass re-preintegrates at the first pass's biases, so that the first-order
  // bias correction is taken where it is accurate.
  for (int pass = 0; pass < 2; ++pass) {
    std::vector<std::unique_ptr<NavFactor>> factors;
    for (int k = 0; k < n; ++k) factors.push_back(std::make_unique<NavPriorFactor>(k, traj.state(0.25 * k), info));
    for (int k = 0; k + 1 < n; ++k) {
      ImuPreintegration pre(states[k].bias, noise);
      pre.integrate(samples, 0.25 * k, 0.25 * (k + 1));
      factors.push_back(std::make_unique<ImuFactor>(k, k + 1, pre));
      factors.push_back(std::make_unique<BiasRandomWalkFactor>(k, k + 1, 0.25, noise));
    }
    const NavOptimizationResult result = optimize_nav_states(factors, states);
    EXPECT_LT(result.final_error, result.initial_error);
  }
  for (int k = 0; k < n; ++k) {
    const NavState truth = traj.state(0.25 * k, bias);
    EXPECT_LT((states[k].velocity - truth.velocity).norm(), 1e-4) << "state " << k;
    EXPECT_LT((states[k].bias.gyro - bias.gyro).norm(), 1e-4) << "state " << k;
    EXPECT_LT((states[k].bias.accel - bias.accel).norm(), 1e-3) << "state " << k;
  }
  std::vector<std::unique_ptr<NavFactor>> bad;
  bad.push_back(std::make_unique<BiasRandomWalkFactor>(0, 9, 0.25, noise));
  EXPECT_THROW(optimize_nav_states(bad, states), Error);
}

}  // namespace
}  // namespace gcmap
