// What the lane-kernel tests share: the widths they run every kernel at,
// bit-for-bit comparison (a kernel must give its scalar statement's bits,
// not a close value), and seeded random inputs.
#pragma once

#include <cstdint>
#include <cstring>
#include <random>

#include "tracer/vec3.h"

namespace rayfarm {

// SSE2, AVX2 and the widest (AVX-512 where the CPU has it); a CPU without a
// width gets the next narrower one, which is then tested twice.
inline const char* const kLaneWidths[] = {"sse2", "avx2", ""};

inline bool same_bits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }
inline bool same_bits(const Vec3& a, const Vec3& b) {
  return same_bits(a.x, b.x) && same_bits(a.y, b.y) && same_bits(a.z, b.z);
}

// Random numbers and points from a fixed seed: the same inputs on every run.
class RandomInputs {
 public:
  explicit RandomInputs(uint64_t seed) : rng_(seed) {}
  double uniform(double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(rng_); }
  // A point in the cube [-r, r]^3.
  Vec3 point(double r) { return {uniform(-r, r), uniform(-r, r), uniform(-r, r)}; }

 private:
  std::mt19937_64 rng_;
};

}  // namespace rayfarm
