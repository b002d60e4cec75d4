// libFuzzer target: trajectories (KITTI, TUM, `vN x y z qx qy qz qw` lines) and KITTI calib.txt.
#include <cmath>

#include "fuzz_util.hpp"
#include "gcmap/core/error.hpp"
#include "gcmap/io/trajectory_io.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string_view text = gcmap::fuzz::bytes(data, size);
  try {
    const gcmap::Trajectory traj = gcmap::parse_trajectory(text, "fuzz.txt");
    for (const auto& T : traj.poses)
      if (!T.matrix().allFinite()) std::abort();  // the reader promises finite poses
  } catch (const gcmap::Error&) {}
  try {
    if (!gcmap::parse_kitti_calib_tr(text, "calib.txt").matrix().allFinite()) std::abort();
  } catch (const gcmap::Error&) {}
  return 0;
}
