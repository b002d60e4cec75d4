#pragma once
#include <string>

namespace gcmap {

// IRLS weights as a function of the whitened residual norm r = sqrt(e^T Lambda e).
// shifted Tukey (paper Eq. 11-12): tukey(x, w) = max(0, 1 - x^2/w)^2, weight = tukey(|r - offset|, w):
// strongest at r = offset, zero once the constraint is satisfied (|r - offset| >= sqrt(w)) and for
// grossly wrong constraints; between, it steers.
struct RobustKernel {
  enum class Type { none, huber, shifted_tukey };
  Type type = Type::none;
  double width = 1.0;   // Huber threshold k, or Tukey w
  double offset = 0.0;  // shifted Tukey only

  double weight(double r) const;
  static RobustKernel none() { return {}; }
  static RobustKernel huber(double k) { return {Type::huber, k, 0.0}; }
  static RobustKernel shifted_tukey(double w, double offset) { return {Type::shifted_tukey, w, offset}; }
  static RobustKernel parse(const std::string& name, double width, double offset);
  std::string name() const;
};

inline double tukey_weight(double x, double w) {
  const double s = 1.0 - x * x / w;
  return s > 0.0 ? s * s : 0.0;
}

}  // namespace gcmap
