#include "gcmap/graph/imu_factors.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <string>

#include "gcmap/core/error.hpp"

namespace gcmap {

namespace {
// U with U^T U = information, so that |U r|^2 = r^T information r.
template <int N>
Eigen::Matrix<double, N, N> sqrt_of(const Eigen::Matrix<double, N, N>& information) {
  return information.llt().matrixU();
}

// The same for an information that may be singular by design (a registration's degenerate
// translations dropped): a Cholesky factor's pivot there is rounding noise, and dividing by it
// spreads the noise into the rows after it, so that a direction without information would pull.
// There the eigendecomposition keeps the null space null.
Matrix6d sqrt_of_singular(const Matrix6d& information) {
  const Eigen::SelfAdjointEigenSolver<Matrix6d> eig(0.5 * (information + information.transpose()));
  constexpr double kSingular = 1e-9;  // of the largest eigenvalue
  if (eig.eigenvalues()(0) > kSingular * eig.eigenvalues()(5)) return sqrt_of<6>(information);
  return eig.eigenvalues().cwiseMax(0.0).cwiseSqrt().asDiagonal() * eig.eigenvectors().transpose();
}
}  // namespace

ImuFactor::ImuFactor(int key_i, int key_j, ImuPreintegration preintegration, const Eigen::Vector3d& gravity)
    : pre_(std::move(preintegration)), gravity_(gravity) {
  keys_ = {key_i, key_j};
  // A floor keeps a noise-free (or very short) preintegration invertible.
  const Matrix9d cov = pre_.covariance() + 1e-12 * Matrix9d::Identity();
  sqrt_information_ = sqrt_of<9>(cov.inverse());
}

Vector9d ImuFactor::residual(const NavState& i, const NavState& j, Eigen::Matrix<double, 9, 15>* J_i,
                             Eigen::Matrix<double, 9, 15>* J_j) const {
  const Eigen::Matrix3d &R_i = i.T_world_imu.linear(), &R_j = j.T_world_imu.linear();
  const Eigen::Vector3d &p_i = i.T_world_imu.translation(), &p_j = j.T_world_imu.translation();
  const double dt = pre_.dt();
  const Eigen::Vector3d dbg = i.bias.gyro - pre_.bias_lin().gyro;
  const Eigen::Matrix3d dR = pre_.corrected_delta_R(i.bias);
  const Eigen::Vector3d v_term = R_i.transpose() * (j.velocity - i.velocity - gravity_ * dt);
  const Eigen::Vector3d p_term = R_i.transpose() * (p_j - p_i - i.velocity * dt - 0.5 * gravity_ * dt * dt);
  Vector9d r;
  r.head<3>() = so3_log(dR.transpose() * R_i.transpose() * R_j);
  r.segment<3>(3) = v_term - pre_.corrected_delta_v(i.bias);
  r.tail<3>() = p_term - pre_.corrected_delta_p(i.bias);
  if (!J_i || !J_j) return r;

  const Eigen::Matrix3d Jr_inv = so3_right_jacobian_inverse(r.head<3>());
  J_i->setZero();
  J_i->block<3, 3>(0, 0) = -Jr_inv * R_j.transpose() * R_i;
  J_i->block<3, 3>(0, 9) = -Jr_inv * so3_exp(r.head<3>()).transpose() * so3_right_jacobian(pre_.dR_dbg() * dbg) * pre_.dR_dbg();
  J_i->block<3, 3>(3, 0) = skew(v_term);
  J_i->block<3, 3>(3, 6) = -R_i.transpose();
  J_i->block<3, 3>(3, 9) = -pre_.dv_dbg();
  J_i->block<3, 3>(3, 12) = -pre_.dv_dba();
  J_i->block<3, 3>(6, 0) = skew(p_term);
  J_i->block<3, 3>(6, 3) = -Eigen::Matrix3d::Identity();
  J_i->block<3, 3>(6, 6) = -R_i.transpose() * dt;
  J_i->block<3, 3>(6, 9) = -pre_.dp_dbg();
  J_i->block<3, 3>(6, 12) = -pre_.dp_dba();
  J_j->setZero();
  J_j->block<3, 3>(0, 0) = Jr_inv;
  J_j->block<3, 3>(3, 6) = R_i.transpose();
  J_j->block<3, 3>(6, 3) = R_i.transpose() * R_j;
  return r;
}

Eigen::Matrix<double, 9, 3> ImuFactor::gravity_jacobian(const NavState& i) const {
  const Eigen::Matrix3d Rt = i.T_world_imu.linear().transpose();
  const double dt = pre_.dt();
  Eigen::Matrix<double, 9, 3> J = Eigen::Matrix<double, 9, 3>::Zero();
  J.middleRows<3>(3) = -dt * Rt;
  J.bottomRows<3>() = -0.5 * dt * dt * Rt;
  return sqrt_information_ * J;
}

NavLinearization ImuFactor::linearize(const NavState* const* states) const {
  Eigen::Matrix<double, 9, 15> J_i, J_j;
  NavLinearization out;
  out.r = sqrt_information_ * residual(*states[0], *states[1], &J_i, &J_j);
  out.J[0] = sqrt_information_ * J_i;
  out.J[1] = sqrt_information_ * J_j;
  return out;
}

BiasRandomWalkFactor::BiasRandomWalkFactor(int key_i, int key_j, double dt, const ImuNoise& noise) {
  keys_ = {key_i, key_j};
  const double dt_floor = std::max(dt, 1e-9);
  sqrt_information_ << Eigen::Vector3d::Constant(1.0 / (noise.gyro_bias_walk * std::sqrt(dt_floor))),
      Eigen::Vector3d::Constant(1.0 / (noise.accel_bias_walk * std::sqrt(dt_floor)));
}

NavLinearization BiasRandomWalkFactor::linearize(const NavState* const* states) const {
  NavLinearization out;
  const Eigen::DiagonalMatrix<double, 6> W(sqrt_information_);
  out.r = W * (states[1]->bias.vector() - states[0]->bias.vector());
  for (int k = 0; k < 2; ++k) {
    out.J[k] = Eigen::MatrixXd::Zero(6, 15);
    out.J[k].rightCols<6>() = (k == 0 ? -1.0 : 1.0) * Eigen::MatrixXd(W);
  }
  return out;
}

NavPriorFactor::NavPriorFactor(int key, const NavState& prior, const Matrix15d& information)
    : prior_(prior), sqrt_information_(sqrt_of<15>(information)) {
  keys_ = {key, -1};
}

NavLinearization NavPriorFactor::linearize(const NavState* const* states) const {
  const NavState& s = *states[0];
  Vector15d r;
  r.head<6>() = se3_log(prior_.T_world_imu.inverse() * s.T_world_imu);
  r.segment<3>(6) = s.velocity - prior_.velocity;
  r.tail<6>() = s.bias.vector() - prior_.bias.vector();
  Matrix15d J = Matrix15d::Identity();
  J.topLeftCorner<6, 6>() = se3_right_jacobian_inverse(r.head<6>());
  NavLinearization out;
  out.r = sqrt_information_ * r;
  out.J[0] = sqrt_information_ * J;
  return out;
}

LidarPoseFactor::LidarPoseFactor(int key, const Eigen::Isometry3d& T_world_lidar, const Matrix6d& information,
                                 const Eigen::Isometry3d& T_imu_lidar)
    : T_world_lidar_(T_world_lidar), T_imu_lidar_(T_imu_lidar), sqrt_information_(sqrt_of_singular(information)) {
  keys_ = {key, -1};
}

Vector6d pose_difference(const Eigen::Isometry3d& T_measured, const Eigen::Isometry3d& T) {
  const Eigen::Matrix3d& R = T_measured.linear();
  return (Vector6d() << so3_log(R.transpose() * T.linear()), R.transpose() * (T.translation() - T_measured.translation()))
      .finished();
}

NavLinearization LidarPoseFactor::linearize(const NavState* const* states) const {
  const Eigen::Isometry3d T = states[0]->T_world_imu * T_imu_lidar_;
  const Vector6d r = pose_difference(T_world_lidar_, T);
  // T exp(d) T_imu_lidar = T T_imu_lidar exp(Ad(T_lidar_imu) d); the LiDAR's own perturbation
  // [w, v] turns its rotation by exp(w) and moves it by R v (first order).
  Matrix6d J = Matrix6d::Zero();
  J.topLeftCorner<3, 3>() = so3_left_jacobian_inverse(-r.head<3>());
  J.bottomRightCorner<3, 3>() = T_world_lidar_.linear().transpose() * T.linear();
  NavLinearization out;
  out.r = sqrt_information_ * r;
  out.J[0] = Eigen::MatrixXd::Zero(6, 15);
  out.J[0].leftCols<6>() = sqrt_information_ * J * adjoint(T_imu_lidar_.inverse());
  return out;
}

double nav_error(const std::vector<std::unique_ptr<NavFactor>>& factors, const std::vector<NavState>& states) {
  double e = 0.0;
  for (const auto& f : factors) {
    const NavState* s[2] = {&states[f->keys()[0]], f->num_keys() > 1 ? &states[f->keys()[1]] : nullptr};
    e += f->error(s);
  }
  return e;
}

void nav_system(const std::vector<std::unique_ptr<NavFactor>>& factors, const std::vector<NavState>& states, Eigen::MatrixXd& H,
                Eigen::VectorXd& b) {
  const int n = static_cast<int>(states.size()) * 15;
  H = Eigen::MatrixXd::Zero(n, n);
  b = Eigen::VectorXd::Zero(n);
  for (const auto& f : factors) {
    const NavState* s[2] = {&states[f->keys()[0]], f->num_keys() > 1 ? &states[f->keys()[1]] : nullptr};
    const NavLinearization lin = f->linearize(s);
    for (int a = 0; a < f->num_keys(); ++a) {
      b.segment<15>(15 * f->keys()[a]) += lin.J[a].transpose() * lin.r;
      for (int c = 0; c < f->num_keys(); ++c)
        H.block<15, 15>(15 * f->keys()[a], 15 * f->keys()[c]) += lin.J[a].transpose() * lin.J[c];
    }
  }
}

Eigen::MatrixXd nav_information(const std::vector<std::unique_ptr<NavFactor>>& factors, const std::vector<NavState>& states) {
  Eigen::MatrixXd H;
  Eigen::VectorXd b;
  nav_system(factors, states, H, b);
  return H;
}

NavOptimizationResult optimize_nav_states(const std::vector<std::unique_ptr<NavFactor>>& factors, std::vector<NavState>& states,
                                          int max_iterations) {
  for (const auto& f : factors)
    for (int k = 0; k < f->num_keys(); ++k)
      if (f->keys()[k] < 0 || f->keys()[k] >= static_cast<int>(states.size()))
        throw Error("an IMU factor references state " + std::to_string(f->keys()[k]) + ", which has no value");
  std::vector<NavState> moved(states.size());
  return dense_levenberg_marquardt(
      nav_error(factors, states), max_iterations,
      [&](Eigen::MatrixXd& H, Eigen::VectorXd& b) { nav_system(factors, states, H, b); },
      [&](const Eigen::VectorXd& d) {
        for (size_t s = 0; s < states.size(); ++s) moved[s] = states[s].retract(d.segment<15>(15 * s));
        return nav_error(factors, moved);
      },
      [&] { states.swap(moved); });
}

}  // namespace gcmap
