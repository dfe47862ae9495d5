// What the lane-kernel tests share: the widths they run every kernel at, and
// bit-for-bit comparison (a kernel must give its scalar statement's bits,
// not a close value).
#pragma once

#include <cstring>

#include "tracer/vec3.h"

namespace rayfarm {

// SSE2, AVX2 and the widest (AVX-512 where the CPU has it); a CPU without a
// width gets the next narrower one, which is then tested twice.
inline const char* const kLaneWidths[] = {"sse2", "avx2", ""};

inline bool same_bits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }
inline bool same_bits(const Vec3& a, const Vec3& b) {
  return same_bits(a.x, b.x) && same_bits(a.y, b.y) && same_bits(a.z, b.z);
}

}  // namespace rayfarm
