#include "gcmap/graph/lazy_backend.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>

#include "gcmap/core/error.hpp"

namespace gcmap {

namespace {

// How far the factor's relative pose moved since it was kept, as a motion of its first pose with
// the second held (unused part 0; exactly 0 when neither pose changed). A reusable factor's cost
// depends on T_1^-1 T_0 only, so a motion both poses share leaves its model exact.
Vector12d motion(const Factor& f, const FactorPoses& poses) {
  Vector12d d = Vector12d::Zero();
  const auto& kept = f.kept->poses;
  if (f.num_keys() == 1) {
    if (kept[0].matrix() != poses[0]->matrix()) d.head<6>() = se3_log(kept[0].inverse() * *poses[0]);
  } else if (kept[0].matrix() != poses[0]->matrix() || kept[1].matrix() != poses[1]->matrix()) {
    const Eigen::Isometry3d T_kept = kept[1].inverse() * kept[0], T_now = poses[1]->inverse() * *poses[0];
    d.head<6>() = se3_log(T_kept.inverse() * T_now);
  }
  return d;
}

// error(d) ~ e + 2 b^T d + d^T H d (factors.hpp).
double model_error(const FactorLinearization& lin, const Vector12d& d) {
  return lin.error + 2.0 * lin.b.dot(d) + d.dot(lin.H * d);
}

// The kept model at the current poses. A two-pose factor's model is one of its relative pose (the
// first pose's block, whose Jacobian is the identity), turned onto the second pose by the relative
// pose's Jacobian at the current poses, -Ad(T_rel^-1). The kept Jacobian, of the relative pose as it
// was, would leave a force on any motion both poses share, growing with their distance from the
// origin: enough to turn a map that gravity alone holds level.
FactorLinearization carried(const Factor& f, const FactorPoses& poses, const Vector12d& d) {
  const FactorLinearization& kept = f.kept->lin;
  FactorLinearization out;
  out.error = model_error(kept, d);
  if (f.num_keys() == 1) {
    out.H = kept.H;
    out.b = kept.b + kept.H * d;
    return out;
  }
  const Matrix6d H = kept.H.topLeftCorner<6, 6>();
  const Vector6d b = kept.b.head<6>() + H * d.head<6>();
  const Matrix6d J1 = -adjoint(poses[0]->inverse() * *poses[1]);
  out.H.topLeftCorner<6, 6>() = H;
  out.H.topRightCorner<6, 6>() = H * J1;
  out.H.bottomLeftCorner<6, 6>() = J1.transpose() * H;
  out.H.bottomRightCorner<6, 6>() = J1.transpose() * H * J1;
  out.b.head<6>() = b;
  out.b.tail<6>() = J1.transpose() * b;
  return out;
}

}  // namespace

LazyBackend::LazyBackend(std::shared_ptr<LinearizationBackend> inner, double threshold)
    : inner_(std::move(inner)), threshold_(threshold) {
  if (!inner_) throw Error("LazyBackend: no inner backend");
}

void LazyBackend::linearize(std::span<Factor* const> factors, std::span<const FactorPoses> poses,
                            std::span<FactorLinearization> out) {
  const size_t n = factors.size();
  modelled_.assign(n, 0);
  std::vector<Vector12d>& d = motion_;
  d.resize(n);
  tbb::parallel_for(size_t{0}, n, [&](size_t f) {
    const Factor& factor = *factors[f];
    if (!factor.reusable() || !factor.kept) return;
    d[f] = motion(factor, poses[f]);
    modelled_[f] = d[f].norm() <= threshold_;
  });
  subset_.clear();
  moved_.clear();
  for (size_t f = 0; f < n; ++f) {
    if (modelled_[f]) continue;
    if (factors[f]->reusable() && factors[f]->kept) moved_.push_back(f);
    else subset_.push_back(f);  // no model to stand in
  }
  if (max_relinearizations_ > 0 && moved_.size() > max_relinearizations_) {
    // Over budget: those that moved most first; the others keep their models until a later call.
    const auto further = [&](size_t a, size_t b) {
      const double da = d[a].squaredNorm(), db = d[b].squaredNorm();
      return da > db || (da == db && a < b);  // ties by index: the same choice on every machine
    };
    const auto budget = moved_.begin() + static_cast<std::ptrdiff_t>(max_relinearizations_);
    std::nth_element(moved_.begin(), budget, moved_.end(), further);
    for (size_t i = max_relinearizations_; i < moved_.size(); ++i) modelled_[moved_[i]] = 1;
    deferred_ += moved_.size() - max_relinearizations_;
    moved_.resize(max_relinearizations_);
  }
  subset_.insert(subset_.end(), moved_.begin(), moved_.end());
  std::sort(subset_.begin(), subset_.end());
  sub_factors_.resize(subset_.size());
  sub_poses_.resize(subset_.size());
  sub_lin_.resize(subset_.size());
  for (size_t i = 0; i < subset_.size(); ++i) {
    sub_factors_[i] = factors[subset_[i]];
    sub_poses_[i] = poses[subset_[i]];
  }
  inner_->linearize(sub_factors_, sub_poses_, sub_lin_);
  tbb::parallel_for(size_t{0}, subset_.size(), [&](size_t i) {
    Factor& factor = *sub_factors_[i];
    out[subset_[i]] = sub_lin_[i];
    if (!factor.reusable()) return;
    const FactorPoses& at = sub_poses_[i];
    factor.kept = Factor::Kept{{*at[0], factor.num_keys() > 1 ? *at[1] : *at[0]}, sub_lin_[i]};
  });
  tbb::parallel_for(size_t{0}, n, [&](size_t f) {
    if (modelled_[f]) out[f] = carried(*factors[f], poses[f], d[f]);
  });
  linearized_ += subset_.size();
  reused_ += n - subset_.size();
}

void LazyBackend::trial_errors(std::span<Factor* const> factors, std::span<const FactorPoses> poses, std::span<double> out) {
  if (modelled_.size() != factors.size()) throw Error("LazyBackend: trial errors for other factors than were linearized");
  sub_poses_.resize(subset_.size());
  sub_errors_.resize(subset_.size());
  for (size_t i = 0; i < subset_.size(); ++i) sub_poses_[i] = poses[subset_[i]];
  inner_->trial_errors(sub_factors_, sub_poses_, sub_errors_);
  for (size_t i = 0; i < subset_.size(); ++i) out[subset_[i]] = sub_errors_[i];
  tbb::parallel_for(size_t{0}, factors.size(), [&](size_t f) {
    if (modelled_[f]) out[f] = model_error(factors[f]->kept->lin, motion(*factors[f], poses[f]));
  });
}

}  // namespace gcmap
