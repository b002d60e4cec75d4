// Pair registration on consecutive raw KITTI scans: ms per pair split into preprocess / voxel map /
// align, and VGICP linearization throughput, for 1 and 2 threads. Not a test.
#include <tbb/global_control.h>

#include <cstdio>
#include <filesystem>

#include "gcmap/core/preprocess.hpp"
#include "gcmap/core/memory.hpp"
#include "gcmap/core/timer.hpp"
#include "gcmap/io/point_cloud_io.hpp"
#include "gcmap/registration/registration.hpp"
#include "gcmap/registration/vgicp.hpp"

using namespace gcmap;

int main() {
  keep_large_buffers_in_heap();  // as gcmap does
  const std::string dir = std::string(GCMAP_SHARED_DATA) + "/kitti00_first16/velodyne";
  if (!std::filesystem::exists(dir)) {
    std::printf("skipped: %s is absent\n", dir.c_str());
    return 0;
  }
  std::vector<PointCloud> raw;
  for (int k = 0; k < 16; ++k) {
    char name[32];
    std::snprintf(name, sizeof(name), "/%06d.bin", k);
    raw.push_back(read_point_cloud(dir + name));
  }
  for (int threads : {1, 2}) {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
    double t_pre = 0, t_vox = 0, t_align = 0;
    int pairs = 0, iterations = 0;
    // Each scan is preprocessed once and serves as source then target, as in odometry; a pair's
    // cost is one scan's preprocessing + one voxel map + one alignment.
    PointCloud prev;
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    for (int k = 0; k < 16; ++k) {
      Stopwatch w;
      PointCloud cur = voxel_downsample(raw[k], 0.25);
      estimate_covariances(cur);
      t_pre += w.lap_ms();
      if (k > 0) {
        GaussianVoxelMap voxels(1.0);
        voxels.insert(prev);
        voxels.finalize();
        t_vox += w.lap_ms();
        const RegistrationResult r = align_vgicp(cur, voxels, T);
        t_align += w.lap_ms();
        T = r.T_target_source;
        iterations += r.iterations;
        ++pairs;
      }
      prev = std::move(cur);
    }
    const double per = 1.0 / pairs;
    std::printf("threads=%d  ms/pair: preprocess %.1f  voxelmap %.1f  align %.1f  total %.1f  (%.1f LM iterations/pair)\n",
                threads, t_pre / 16.0, t_vox * per, t_align * per, t_pre / 16.0 + (t_vox + t_align) * per, iterations * per);

    // Linearization throughput on one pair.
    PointCloud a = voxel_downsample(raw[0], 0.25), b = voxel_downsample(raw[1], 0.25);
    estimate_covariances(a);
    estimate_covariances(b);
    GaussianVoxelMap voxels(1.0);
    voxels.insert(a);
    voxels.finalize();
    const int reps = 200;
    Stopwatch w;
    double sink = 0;
    for (int r = 0; r < reps; ++r) sink += linearize_vgicp(b, voxels, T).error;
    const double s = w.ms() / 1000.0;
    std::printf("threads=%d  linearization: %zu points x %d in %.1f ms -> %.1f M point evaluations/s (checksum %.3g)\n", threads,
                b.size(), reps, s * 1000, b.size() * reps / s / 1e6, sink);
  }
  return 0;
}
