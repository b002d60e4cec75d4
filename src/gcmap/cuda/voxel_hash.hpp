#pragma once
// The device voxel table's probing logic, shared by the CUDA kernels and the host (where tests
// exercise it without a GPU). Open addressing with linear probing, bounded: an insertion that finds
// no free slot within kMaxProbes reports failure and the owner grows the table; a lookup never
// looks further than an insertion could have gone, so neither loop is unbounded.
#include <cmath>
#include <cstdint>

#if defined(__CUDACC__)
#define GCMAP_HD __host__ __device__ __forceinline__
#else
#define GCMAP_HD inline
#endif

namespace gcmap::cuda {

constexpr int kMaxProbes = 32;

struct VoxelSlot {
  int32_t x, y, z;
  int32_t index;  // voxel index in the map's arrays, -1: empty
};

GCMAP_HD uint32_t voxel_slot_hash(int32_t x, int32_t y, int32_t z) {
  // 32-bit multiplicative mixing: the device has no fast 64-bit multiply-high.
  uint32_t h = static_cast<uint32_t>(x) * 73856093u;
  h ^= static_cast<uint32_t>(y) * 19349669u;
  h ^= static_cast<uint32_t>(z) * 83492791u;
  h ^= h >> 16;
  h *= 0x85ebca6bu;
  h ^= h >> 13;
  return h;
}

// Claims a slot for a coordinate known to be absent (the map's voxels are unique), with
// `claim(slot_index_field) -> bool` doing the compare-and-swap of -1 to `index`.
template <class Claim>
GCMAP_HD bool voxel_table_insert(VoxelSlot* slots, uint32_t mask, int32_t x, int32_t y, int32_t z, int32_t index, Claim claim) {
  uint32_t s = voxel_slot_hash(x, y, z) & mask;
  for (int probe = 0; probe < kMaxProbes; ++probe) {
    if (claim(&slots[s].index, index)) {
      slots[s].x = x;
      slots[s].y = y;
      slots[s].z = z;
      return true;
    }
    s = (s + 1) & mask;
  }
  return false;
}

GCMAP_HD int32_t voxel_table_find(const VoxelSlot* slots, uint32_t mask, int32_t x, int32_t y, int32_t z) {
  uint32_t s = voxel_slot_hash(x, y, z) & mask;
  for (int probe = 0; probe < kMaxProbes; ++probe) {
    const VoxelSlot& slot = slots[s];
    if (slot.index < 0) return -1;
    if (slot.x == x && slot.y == y && slot.z == z) return slot.index;
    s = (s + 1) & mask;
  }
  return -1;
}

// Slots for n voxels at the initial load factor of at most 1/2 (a power of two).
inline uint32_t voxel_table_capacity(size_t n) {
  uint32_t c = 16;
  while (c < 2 * n && c < (1u << 31)) c <<= 1;
  return c;
}

// The growth policy: try_build(slots) -> false when an insertion ran out of probes; the table
// doubles until it fits or would exceed max_slots. Returns the slots used, 0 at the cap.
template <class TryBuild>
uint32_t grow_voxel_table(size_t n, uint32_t max_slots, TryBuild try_build) {
  for (uint64_t slots = voxel_table_capacity(n); slots <= max_slots; slots <<= 1) {
    if (try_build(static_cast<uint32_t>(slots))) return static_cast<uint32_t>(slots);
  }
  return 0;
}

}  // namespace gcmap::cuda
