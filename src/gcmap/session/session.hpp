#pragma once
// A mapping run kept on disk so that later runs can localize in it or merge it (OUT/session/).
//
// Format, version 2 (all binary values little endian):
//   manifest.yaml  format: gcmap-session, version, created_by, frames, submaps, and every global
//                  factor as [kind, source, target, overlap]
//   config.yaml    the MappingConfig of the run
//   trajectory.tum every frame's optimized pose with its stamp (frame 0 the identity)
//   submaps.bin    "GCMAPSM1", u32 version, u32 count, then per submap: i32 id, f64[7] T_world_submap
//                  and f64[7] T_odom (x y z qx qy qz qw), u32 keyframes, per keyframe i32 frame and
//                  f64[7] T_submap_keyframe, u32 rings, u32 sectors (0 0: no descriptors), per
//                  keyframe rings x sectors cells and rings ring-key floats, u32 points, f32[3] per
//                  point, f32[6] per point (covariance xx xy xz yy yz zz), u8 intensities (0 or 1),
//                  then when 1 f32 per point (mean intensity of the voxel)
// Version 1 is read too: the same without the intensity flag and block (clouds without intensity).
// The folder is written beside the old one and swapped with it in one rename (RENAME_EXCHANGE;
// elsewhere two renames): a crash leaves the old or the new.
#include <functional>
#include <string>
#include <vector>

#include "gcmap/mapping/pipeline.hpp"

namespace gcmap {

inline constexpr int kSessionVersion = 2;

using SessionFactor = FactorRecord;

struct Session {
  int version = kSessionVersion;
  std::string created_by;
  MappingConfig config;
  // Clouds with covariances (and intensities when the run had them) in the submap frame; voxels
  // and factor_source rebuilt from the config.
  std::vector<Submap> submaps;
  std::vector<Eigen::Isometry3d> T_world_submap;  // optimized, in the output frame
  std::vector<SessionFactor> factors;
  std::vector<double> stamps;                 // per frame
  std::vector<Eigen::Isometry3d> trajectory;  // per frame
};

// The session of a finished pipeline (poses in its output frame); stamps per frame.
Session make_session(const MappingPipeline& pipeline, const std::vector<double>& stamps);
// Writes DIR (e.g. OUT/session); version and created_by are written as this gcmap's.
void write_session(const std::string& dir, const Session& session);
void write_session(const std::string& dir, const MappingPipeline& pipeline, const std::vector<double>& stamps);
// Throws Error naming the file for anything missing, truncated or of a newer version. progress(done,
// total): submaps made ready (voxel maps rebuilt), for a person.
Session read_session(const std::string& dir, const std::function<void(size_t done, size_t total)>& progress = {});

struct SessionInfo {
  int version = 0;
  std::string created_by;
  size_t frames = 0, submaps = 0, keyframes = 0, points = 0, factors = 0;
  bool intensities = false;    // every submap cloud has them
  Eigen::AlignedBox3d extent;  // of the submap clouds in the world frame
  uintmax_t bytes = 0;         // on disk
};
SessionInfo session_info(const Session& session, const std::string& dir);

}  // namespace gcmap
