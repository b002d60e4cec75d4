#include "gcmap/graph/robust_kernel.hpp"

#include <cmath>

#include "gcmap/core/error.hpp"

namespace gcmap {

double RobustKernel::weight(double r) const {
  switch (type) {
    case Type::none: return 1.0;
    case Type::huber: return r <= width ? 1.0 : width / r;
    case Type::shifted_tukey: return tukey_weight(std::abs(r - offset), width);
  }
  return 1.0;
}

RobustKernel RobustKernel::parse(const std::string& name, double width, double offset) {
  if (!(width > 0.0)) throw Error("robust kernel width must be positive");
  if (name == "none") return none();
  if (name == "huber") return huber(width);
  if (name == "shifted_tukey" || name == "shifted-tukey") return shifted_tukey(width, offset);
  throw Error("unknown robust kernel '" + name + "' (none, huber, shifted_tukey)");
}

std::string RobustKernel::name() const {
  switch (type) {
    case Type::none: return "none";
    case Type::huber: return "huber";
    case Type::shifted_tukey: return "shifted_tukey";
  }
  return "none";
}

}  // namespace gcmap
