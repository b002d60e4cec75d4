#pragma once
// A trajectory's rotations refined with the gyro's rotations between consecutive frames. A sparse
// sensor's registrations turn frames by tenths of a degree against each other where the gyro is
// off by hundredths over a sweep; each frame's rotation is then taken from its neighbours through
// the gyro as well as from itself. Positions are left as they are.
#include <optional>
#include <vector>

#include "gcmap/core/imu_sample.hpp"
#include "gcmap/core/se3.hpp"

namespace gcmap {

struct RotationSmoothing {
  size_t windows = 0;            // runs of kRotationNoiseSpan frames the noise was measured over
  double frame_noise_deg = 0.0;  // the trajectory's own rotation noise per frame and axis, against the gyro
  double gyro_noise_deg = 0.0;   // the gyro's between consecutive frames (median), per axis
  bool applied = false;          // only where the frames are noisier than the gyro between them
};

// Frames a window spans when the trajectory's noise is measured: its errors are correlated over
// a few frames (they ride on the keyframe they are placed from), so consecutive frames alone hide
// most of it.
inline constexpr int kRotationNoiseSpan = 5;

// gyro[k]: the rotation from frame k-1 to frame k in frame k-1's frame, with its variance per axis
// (rad^2); empty where the gyro does not span the interval, which splits the chain (gyro[0] is
// unused). Measures how far the trajectory's rotations between frames kRotationNoiseSpan apart
// disagree with the gyro's; where that is more than the gyro explains, each rotation R_k is
// re-estimated by least squares on Log(R_k_given^T R_k) (sigma: twice the measured noise, for its
// correlation) and Log(gyro[k]^T R_{k-1}^T R_k) (the gyro's variance), solved along the chain.
RotationSmoothing smooth_rotations(std::vector<Eigen::Isometry3d>& poses, const std::vector<std::optional<GyroRotation>>& gyro);

}  // namespace gcmap
