#pragma once
// A counter-based random source for the simulator: every draw is a pure function of its key, so
// results do not depend on which thread simulates what.
#include <cmath>
#include <cstdint>

namespace gcmap::sim {

inline uint64_t mix64(uint64_t x) {  // splitmix64 finalizer
  x += 0x9e3779b97f4a7c15ull;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
  return x ^ (x >> 31);
}
inline uint64_t hash_key(uint64_t a, uint64_t b) { return mix64(a ^ mix64(b)); }
inline uint64_t hash_key(uint64_t a, uint64_t b, uint64_t c) { return hash_key(hash_key(a, b), c); }

// Uniform in [0, 1) from the top 24 bits.
inline float unit_float(uint64_t h) { return static_cast<float>(h >> 40) * (1.f / 16777216.f); }

class Rng {
 public:
  explicit Rng(uint64_t key) : state_(key) {}
  uint64_t next() { return mix64(state_ += 0x632be59bd9b4e019ull); }
  float uniform() { return unit_float(next()); }
  float uniform(float lo, float hi) { return lo + (hi - lo) * uniform(); }
  float normal() {  // Box-Muller, one value per call
    const float u1 = 1.f - uniform(), u2 = uniform();
    return std::sqrt(-2.f * std::log(u1)) * std::cos(6.2831853f * u2);
  }

 private:
  uint64_t state_;
};

}  // namespace gcmap::sim
