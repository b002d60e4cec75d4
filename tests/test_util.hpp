#pragma once
#include <gtest/gtest.h>

#include <sys/wait.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <string>

#include "gcmap/core/se3.hpp"

namespace gcmap::test {

// ../shared/data beside the repository; tests that need it skip when it is absent.
inline std::string shared_data() { return GCMAP_SHARED_DATA; }
#define GCMAP_REQUIRE_SHARED_DATA(sub)                                                         \
  do {                                                                                         \
    if (!std::filesystem::exists(::gcmap::test::shared_data() + "/" + (sub)))                  \
      GTEST_SKIP() << "../shared/data/" << (sub) << " is absent: skipping the real-data test"; \
  } while (0)

inline Eigen::Isometry3d random_pose(std::mt19937_64& rng, double rot, double trans) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Vector6d xi;
  for (int k = 0; k < 3; ++k) xi[k] = rot * u(rng);
  for (int k = 3; k < 6; ++k) xi[k] = trans * u(rng);
  return se3_exp(xi);
}

inline double translation_error(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return (a.inverse() * b).translation().norm();
}
inline double rotation_error_deg(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return rotation_angle(a.inverse() * b) * 180.0 / M_PI;
}

// A fresh, empty temporary folder removed when the object dies.
struct TempDir {
  std::filesystem::path path;
  TempDir() {
    path = std::filesystem::temp_directory_path() / ("gcmap_test_" + std::to_string(std::random_device{}()));
    std::filesystem::create_directories(path);
  }
  ~TempDir() { std::filesystem::remove_all(path); }
  std::string operator/(const std::string& name) const { return (path / name).string(); }
};

inline std::string slurp(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

#ifdef GCMAP_CLI
struct CliRun {
  int code;
  std::string out, err;
};

// The gcmap command line with `args`: its exit code and what it printed.
inline CliRun run_gcmap(const std::string& args) {
  TempDir tmp;
  const int status = std::system((std::string(GCMAP_CLI) + " " + args + " >" + (tmp / "out") + " 2>" + (tmp / "err")).c_str());
  return {WEXITSTATUS(status), slurp(tmp / "out"), slurp(tmp / "err")};
}
#endif

}  // namespace gcmap::test
