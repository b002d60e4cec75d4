#pragma once
// Verification of a loop candidate and the constraint it becomes (paper Section III-C).
#include <string>

#include "gcmap/graph/factors.hpp"
#include "gcmap/loop/scan_context.hpp"

namespace gcmap {

// Explicit loops (paper Section III-C): ScanContext candidates between keyframes, GICP
// verification of the submap pair, an SE(3) constraint with a shifted Tukey kernel.
// Each key's meaning, unit and valid range: the config table (mapping/config.cpp), docs/config.md.
struct LoopConfig {
  bool enabled = true;
  ScanContextConfig scan_context;
  int exclude_recent = 5;                 // submaps before the current one that are not searched
  int num_candidates = 10;                // ring-key neighbours matched in full
  double max_descriptor_distance = 0.15;  // strict: a false loop costs more than a missed one
  double verification_downsample = 0.5;   // m, both submaps before GICP
  double inlier_distance = 0.3;           // m, after GICP
  // Strict, and the plane distance decides: in a regular street grid wrong blocks align many points
  // too, but farther from their planes than true revisits. Scale max_inlier_rmse with the sensor's noise
  // and the covariances' neighbourhood (docs/pipeline.md).
  double min_inlier_fraction = 0.6;
  double max_inlier_rmse = 0.04;  // m, point-to-plane
  // A featureless tunnel aligns just as well 100 m further on: the alignment must hold the
  // translation in every direction (translation_conditioning of the verification's alignment).
  double min_conditioning = 0.03;
  // Constant information of the constraint (sigmas), and the shifted Tukey kernel on its whitened
  // residual r: with the defaults the pull peaks at r = 1000 (10 m of translation), fades to zero
  // below r = 5 (5 cm: the matching-cost factors decide) and above r = 1995 (grossly wrong).
  double rotation_sigma_deg = 0.05;
  double translation_sigma = 0.01;  // m
  double tukey_width = 990025.0;    // w: zero weight where |r - offset| >= sqrt(w)
  double tukey_offset = 1000.0;
};

struct LoopVerification {
  bool accepted = false;
  Eigen::Isometry3d T_target_source = Eigen::Isometry3d::Identity();
  double inlier_fraction = 0.0;  // source points with a target point within inlier_distance
  double inlier_rmse = 0.0;      // m, point-to-plane, over those points
  double conditioning = 0.0;     // translation_conditioning of the final alignment
};

// GICP (kNN) from `init`, coarse to fine, on both clouds downsampled; accepted only on a high
// inlier fraction, a low inlier RMSE and a translation held in every direction. Both clouds need
// covariances.
LoopVerification verify_loop(const PointCloud& source, const PointCloud& target, const Eigen::Isometry3d& init,
                             const LoopConfig& config);

// The constraint T_target^-1 T_source ~ measured with constant information and the shifted Tukey
// kernel: it pulls while the estimate is far from the loop, lets go once it is satisfied, and
// ignores grossly wrong loops.
std::shared_ptr<RelativePoseFactor> make_loop_factor(int target_key, int source_key, const Eigen::Isometry3d& T_target_source,
                                                     const LoopConfig& config);

}  // namespace gcmap
