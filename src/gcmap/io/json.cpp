#include "gcmap/io/json.hpp"

#include <cmath>
#include <cstdio>

#include "gcmap/core/se3.hpp"

namespace gcmap {

Json& Json::operator[](const std::string& key) {
  if (std::holds_alternative<std::nullptr_t>(value_)) value_ = Object{};
  auto& obj = std::get<Object>(value_);
  for (auto& [k, v] : obj)
    if (k == key) return v;
  obj.emplace_back(key, Json());
  return obj.back().second;
}

std::string Json::dump() const {
  std::string out;
  dump_to(out);
  return out;
}

namespace {
void escape(const std::string& s, std::string& out) {
  out += '"';
  for (char c : s) {
    switch (c) {
      case '"': out += "\\\""; break;
      case '\\': out += "\\\\"; break;
      case '\n': out += "\\n"; break;
      case '\t': out += "\\t"; break;
      default:
        if (static_cast<unsigned char>(c) < 0x20) {
          char buf[8];
          std::snprintf(buf, sizeof(buf), "\\u%04x", c);
          out += buf;
        } else {
          out += c;
        }
    }
  }
  out += '"';
}
}  // namespace

void Json::dump_to(std::string& out) const {
  if (std::holds_alternative<std::nullptr_t>(value_)) {
    out += "null";
  } else if (const bool* b = std::get_if<bool>(&value_)) {
    out += *b ? "true" : "false";
  } else if (const double* d = std::get_if<double>(&value_)) {
    if (!std::isfinite(*d)) {
      out += "null";  // JSON has no NaN/inf
    } else {
      char buf[32];
      std::snprintf(buf, sizeof(buf), "%.10g", *d);
      out += buf;
    }
  } else if (const std::string* s = std::get_if<std::string>(&value_)) {
    escape(*s, out);
  } else if (const Array* a = std::get_if<Array>(&value_)) {
    out += '[';
    for (size_t i = 0; i < a->size(); ++i) {
      if (i) out += ',';
      (*a)[i].dump_to(out);
    }
    out += ']';
  } else {
    const Object& o = std::get<Object>(value_);
    out += '{';
    for (size_t i = 0; i < o.size(); ++i) {
      if (i) out += ',';
      escape(o[i].first, out);
      out += ':';
      o[i].second.dump_to(out);
    }
    out += '}';
  }
}

Json pose_json(const Eigen::Isometry3d& T) {
  double v[7];
  pose_to_xyz_quat(T, v);
  return Json::Array(v, v + 7);
}

}  // namespace gcmap
