#pragma once
// Shared by the bag tests: small synthetic scans and the container variants every test runs over.
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "gcmap/io/bag_scans.hpp"
#include "gcmap/io/file.hpp"

namespace gcmap::test {

// n points in a 60 m box, intensities 0..255 (integers: exact in every layout), times from 0 to
// 0.05 s; with `nan_every`, every k-th point is NaN padding (as organized clouds have).
inline PointCloud make_scan(size_t n, unsigned seed, size_t nan_every = 0) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-30.f, 30.f);
  PointCloud c;
  for (size_t i = 0; i < n; ++i) {
    const bool pad = nan_every && i % nan_every == nan_every - 1;
    c.points.push_back(pad ? Eigen::Vector3f::Constant(std::nanf("")) : Eigen::Vector3f(u(rng), u(rng), u(rng)));
    c.intensities.push_back(float(rng() % 256));
    c.times.push_back(0.05f * float(i) / float(n - 1));
  }
  return c;
}

// The finite points of a cloud, as the readers return them.
inline PointCloud finite_points(const PointCloud& c) {
  std::vector<char> keep(c.size());
  for (size_t i = 0; i < c.size(); ++i) keep[i] = c.points[i].allFinite();
  return c.selected(keep);
}

struct Container {
  std::string name;
  BagFormat format;
  BagWriterOptions options;
};

inline std::vector<Container> containers() {
  auto opt = [](Compression c, bool summary = true, uint64_t per_file = 0) {
    BagWriterOptions o;
    o.compression = c;
    o.chunk_bytes = 6000;  // several chunks per bag
    o.mcap_summary = summary;
    o.db3_messages_per_file = per_file;
    return o;
  };
  return {{"mcap", BagFormat::mcap, opt(Compression::none)},
          {"mcap-zstd", BagFormat::mcap, opt(Compression::zstd)},
          {"mcap-lz4", BagFormat::mcap, opt(Compression::lz4)},
          {"mcap-zstd-nosummary", BagFormat::mcap, opt(Compression::zstd, false)},
          {"bag", BagFormat::ros1, opt(Compression::none)},
          {"bag-bz2", BagFormat::ros1, opt(Compression::bz2)},
          {"bag-lz4", BagFormat::ros1, opt(Compression::lz4)},
          {"db3", BagFormat::db3, opt(Compression::none)},
          {"db3-split", BagFormat::db3, opt(Compression::none, true, 2)}};
}

inline std::string bag_name(const Container& c) {
  return c.name + (c.format == BagFormat::mcap ? ".mcap" : c.format == BagFormat::ros1 ? ".bag" : "");
}

}  // namespace gcmap::test
