#pragma once
// A minimal JSON value for the CLI's machine-readable output (no parsing needed anywhere).
#include <Eigen/Geometry>
#include <cstdint>
#include <map>
#include <string>
#include <utility>
#include <variant>
#include <vector>

namespace gcmap {

class Json {
 public:
  using Array = std::vector<Json>;
  using Object = std::vector<std::pair<std::string, Json>>;  // keeps insertion order

  Json() : value_(nullptr) {}
  Json(bool v) : value_(v) {}
  Json(int v) : value_(static_cast<double>(v)) {}
  Json(long v) : value_(static_cast<double>(v)) {}
  Json(unsigned long v) : value_(static_cast<double>(v)) {}
  Json(unsigned v) : value_(static_cast<double>(v)) {}
  Json(long long v) : value_(static_cast<double>(v)) {}
  Json(double v) : value_(v) {}
  Json(const char* v) : value_(std::string(v)) {}
  Json(std::string v) : value_(std::move(v)) {}
  Json(Array v) : value_(std::move(v)) {}

  static Json object() {
    Json j;
    j.value_ = Object{};
    return j;
  }
  static Json array() { return Json(Array{}); }

  // Object member (created on first use, insertion order kept).
  Json& operator[](const std::string& key);
  // Constructs the element in place (a Json moved in set off GCC 12's -Wmaybe-uninitialized).
  template <typename T>
  void push_back(T&& v) {
    std::get<Array>(value_).emplace_back(std::forward<T>(v));
  }

  std::string dump() const;

 private:
  void dump_to(std::string& out) const;
  std::variant<std::nullptr_t, bool, double, std::string, Array, Object> value_;
};

// [x, y, z, qx, qy, qz, qw], the pose layout of every JSON output.
Json pose_json(const Eigen::Isometry3d& T);

}  // namespace gcmap
