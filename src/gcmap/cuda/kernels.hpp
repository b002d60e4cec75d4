#pragma once
// The device side of the CUDA backend behind a plain C++ interface (no CUDA types), so that the
// rest of gcmap is compiled by the host compiler and the .cu file depends on nothing but this.
// Every call throws gcmap::Error with the CUDA error string when the device fails.
#include <cstddef>
#include <cstdint>
#include <vector>

#include "gcmap/cuda/voxel_hash.hpp"

namespace gcmap::cuda::device {

// Number of usable devices; 0 (and `why`) when the driver or device is missing.
int device_count(const char** why);
void select_device(int index);
const char* device_name();

// Per point: mean (x, y, z, pad) and the covariance's upper triangle (xx xy xz yy yz zz).
struct Cloud {
  float* means = nullptr;
  float* covs = nullptr;
  uint32_t size = 0;
};
Cloud upload_cloud(const float* xyz, const float* cov6, uint32_t n);
void free_cloud(Cloud& c);

struct VoxelMap {
  VoxelSlot* slots = nullptr;
  uint32_t mask = 0;  // slots: mask + 1
  float* means = nullptr;
  float* covs = nullptr;
  uint32_t num_voxels = 0;
  float inv_resolution = 1.f;
};
// Uploads the voxels and builds the table on the device: starts at load <= 1/2 and doubles while an
// insertion runs out of probes, up to max_slots; throws there.
VoxelMap upload_voxel_map(const int32_t* coords, const float* xyz, const float* cov6, uint32_t n, float inv_resolution,
                          uint32_t max_slots);
void free_voxel_map(VoxelMap& m);

// Per factor sums in the target frame, in this order: H_rr upper (6), H_rt row-major (9), H_tt
// upper (6), b_r (3), b_t (3), error, inliers.
constexpr int kSums = 29;

// A fixed set of (source cloud, target map) pairs evaluated together. Points are cut into blocks
// that never straddle two factors; a block reduces its points in shared memory and a second pass
// sums each factor's blocks in double in a fixed order: no atomics, the same result every run.
class Batch {
 public:
  Batch() = default;
  Batch(const Batch&) = delete;
  Batch& operator=(const Batch&) = delete;
  ~Batch();

  // robust_widths: per pair, MatchingCostFactor::robust_width() (0: none).
  void set_pairs(const std::vector<Cloud>& sources, const std::vector<VoxelMap>& targets,
                 const std::vector<float>& robust_widths);
  size_t num_pairs() const { return num_pairs_; }
  size_t num_points() const { return num_points_; }
  size_t device_bytes() const { return device_bytes_; }

  // T: per pair T_target_source as a row-major 3x4 float matrix. One upload, two launches, one
  // download. Keeps each point's voxel for trial_errors.
  void linearize(const float* T, double* sums);
  // Per pair error and inlier count at T with the voxels kept by the last linearize().
  void trial_errors(const float* T, double* errors);

 private:
  void release();
  size_t num_pairs_ = 0, num_points_ = 0, num_blocks_ = 0, device_bytes_ = 0;
  void* pairs_ = nullptr;  // device PairView[num_pairs]
  int32_t* block_pair_ = nullptr;
  uint32_t* block_begin_ = nullptr;
  uint32_t* pair_first_block_ = nullptr;  // num_pairs + 1
  int32_t* voxel_of_point_ = nullptr;
  float* poses_ = nullptr;
  float* block_sums_ = nullptr;
  double* pair_sums_ = nullptr;
  std::vector<double> host_sums_;
};

// Grow-only device buffers of overlap_counts.
struct OverlapScratch {
  OverlapScratch() = default;
  OverlapScratch(const OverlapScratch&) = delete;
  OverlapScratch& operator=(const OverlapScratch&) = delete;
  ~OverlapScratch();
  VoxelMap* targets = nullptr;
  float* poses = nullptr;
  uint32_t* block_hits = nullptr;
  size_t target_capacity = 0, block_capacity = 0;
};

// Paper Eq. 8 for one source against many targets in one launch: hits[k] = number of source points
// that land in an occupied voxel of targets[k] under T[k] (row-major 3x4).
void overlap_counts(const Cloud& source, const std::vector<VoxelMap>& targets, const float* T, uint32_t* hits,
                    OverlapScratch& scratch);

// Grow-only device buffers of point_covariances.
struct CovarianceScratch {
  CovarianceScratch() = default;
  CovarianceScratch(const CovarianceScratch&) = delete;
  CovarianceScratch& operator=(const CovarianceScratch&) = delete;
  ~CovarianceScratch();
  float* means = nullptr;
  float* covs = nullptr;
  size_t capacity = 0;
};

// estimate_covariances (core/preprocess.hpp) on the device: per point of xyz (3 per point), the
// covariance's upper triangle (xx xy xz yy yz zz) into cov6, from its k nearest neighbours (itself
// included; exact, by brute force over the cloud) regularized plane-like to eigenvalues
// (epsilon, 1, 1), plus the beam-elevation term when elevation_sigma > 0. k at most kMaxNeighbors.
constexpr int kMaxNeighbors = 32;
void point_covariances(const float* xyz, uint32_t n, int k, double epsilon, double elevation_sigma, float* cov6,
                       CovarianceScratch& scratch);

}  // namespace gcmap::cuda::device
