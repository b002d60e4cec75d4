#pragma once
#ifdef __GLIBC__
#include <malloc.h>
#endif

namespace gcmap {

// Scans, voxel keys and linear systems are large buffers allocated per frame. glibc serves them
// from mmap and gives them back on free, so every frame page-faults them in again, which on a VM
// can cost more than the work (voxel downsampling of a 113k-point scan: 10 ms -> 1.9 ms). Keeps
// them in the heap, which may then hold up to 1 GiB of free memory. For programs, not libraries.
inline void keep_large_buffers_in_heap() {
#ifdef __GLIBC__
  mallopt(M_MMAP_THRESHOLD, 256 << 20);
  mallopt(M_TRIM_THRESHOLD, 1 << 30);
#endif
}

}  // namespace gcmap
