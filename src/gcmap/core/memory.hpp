#pragma once
#include <sys/resource.h>

#include <cstddef>
#ifdef __GLIBC__
#include <malloc.h>
#endif

namespace gcmap {

// Scans, voxel keys and linear systems are large buffers allocated per frame. glibc serves them
// from mmap and gives them back on free, so every frame page-faults them in again, which on a VM
// can cost more than the work itself. Keeps
// them in the heap, which may then hold up to 1 GiB of free memory. For programs, not libraries.
inline void keep_large_buffers_in_heap() {
#ifdef __GLIBC__
  mallopt(M_MMAP_THRESHOLD, 256 << 20);
  mallopt(M_TRIM_THRESHOLD, 1 << 30);
#endif
}

// Peak resident set size of this process so far, in bytes (getrusage); 0 when unavailable.
inline size_t peak_rss_bytes() {
  rusage usage{};
  if (getrusage(RUSAGE_SELF, &usage) != 0) return 0;
#ifdef __APPLE__
  return static_cast<size_t>(usage.ru_maxrss);  // bytes there, KiB on Linux
#else
  return static_cast<size_t>(usage.ru_maxrss) * 1024;
#endif
}

}  // namespace gcmap
