#pragma once
// ScanContext place recognition (Kim & Kim, IROS 2018): a polar grid of maximum heights around the
// sensor, retrieved by a rotation-invariant ring key and matched by column shift (coarse by the
// sector key, refined by the column cosine distance), which also gives the yaw between the scans.
#include <Eigen/Geometry>
#include <vector>

#include "gcmap/core/point_cloud.hpp"

namespace gcmap {

// Each key's (loop.rings, ...) meaning, unit and valid range: the config table (mapping/config.cpp), docs/config.md.
struct ScanContextConfig {
  int rings = 20;
  int sectors = 60;
  double max_radius = 80.0;   // m
  double lidar_height = 2.0;  // m added to z so that ground returns count as occupied cells
};

struct ScanContext {
  int rings = 0, sectors = 0;
  std::vector<float> cells;     // rings x sectors, row-major; 0 = empty
  std::vector<float> ring_key;  // per ring, the mean over sectors

  float at(int ring, int sector) const { return cells[ring * sectors + sector]; }
};

// Points in the sensor frame (z up).
ScanContext make_scan_context(const PointCloud& cloud, const ScanContextConfig& config = {});

struct ScanContextMatch {
  double distance = 1.0;  // mean column cosine distance in [0, 1], at the best shift
  int shift = 0;          // query sector j matches candidate sector (j + shift) mod sectors
  double yaw = 0.0;       // rad: candidate-frame rotation of the query, R_candidate_query = Rz(yaw)
};
ScanContextMatch match_scan_contexts(const ScanContext& query, const ScanContext& candidate);

// Places added in order; a query searches the ring keys of places [0, end) with a kd-tree and
// matches the nearest num_candidates fully. Deterministic: ties go to the older place.
class ScanContextDatabase {
 public:
  void add(ScanContext descriptor) { places_.push_back(std::move(descriptor)); }
  size_t size() const { return places_.size(); }
  const ScanContext& place(size_t i) const { return places_[i]; }

  struct Result {
    int place = -1;
    ScanContextMatch match;
  };
  // One result per query descriptor (place -1: nothing searchable).
  std::vector<Result> query(const std::vector<const ScanContext*>& descriptors, size_t end, int num_candidates) const;
  Result query(const ScanContext& descriptor, size_t end, int num_candidates) const {
    return query(std::vector<const ScanContext*>{&descriptor}, end, num_candidates).front();
  }

 private:
  std::vector<ScanContext> places_;
};

}  // namespace gcmap
