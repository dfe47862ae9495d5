// The lanes of the 16-ray packets rayfarm hands Embree, as bit masks: which
// of them a user-geometry callback is given, which to leave out of a walk,
// and which Embree marked occluded.
//
// Embree hands a 16-ray packet over whole where its ISA walks 16 rays at
// once (AVX-512), and in windows of 8 or 4 consecutive lanes where it walks
// 8 (AVX2) or 4 (SSE). The lane kernels run on the packet's own lanes, so a
// callback must know which of them a window is: the rays' ids say, as
// rayfarm sets ray i's id to i. Taking only whole packets sent every ray
// through the scalar tests on AVX2 machines, where rings, mount and gears
// then took 1.11x, 1.33x and 1.42x the time.
#pragma once

#include <cstdint>

#include <emmintrin.h>
#include <embree3/rtcore.h>

namespace rayfarm {

// Embree's n rays as lanes first..first+n-1 of the packet; `active` holds,
// in the packet's numbering, the lanes Embree marks valid, or is 0 when the
// rays are not such a window.
struct LaneWindow {
  uint32_t active = 0;
  int first = 0;
};

// Bit i set where x[i] == first[i % 4] + (i / 4) * step[i % 4], for n ints,
// n a multiple of 4 up to 16 (SSE2, which every x86-64 runs: a compare per
// four ints instead of a branch per int).
inline uint32_t lanes_equal(const int* x, unsigned n, __m128i first, __m128i step) {
  uint32_t bits = 0;
  for (unsigned q = 0; q < n / 4; ++q, first = _mm_add_epi32(first, step)) {
    const __m128i eq = _mm_cmpeq_epi32(_mm_loadu_si128(reinterpret_cast<const __m128i*>(x + 4 * q)), first);
    bits |= static_cast<uint32_t>(_mm_movemask_ps(_mm_castsi128_ps(eq))) << (4 * q);
  }
  return bits;
}

// The window of a packet of `lanes` lanes (at most 32) that n rays with these
// ids and valid flags (-1 valid, as Embree marks them) are. Embree fills a
// window from consecutive lanes, n of 4, 8 or 16 aligned to n, so its first
// ray's id names the window's first lane; any other width or an id out of
// place (another query's rays, or rays reordered) gives no window.
inline LaneWindow lane_window(const int* valid, const int* ids, unsigned n, int lanes) {
  if ((n != 4 && n != 8 && n != 16) || int(n) > lanes) return {};
  const int first = ids[0] - ids[0] % int(n);
  if (first < 0 || first + int(n) > lanes) return {};
  const uint32_t valid_bits = lanes_equal(valid, n, _mm_set1_epi32(-1), _mm_setzero_si128());
  const uint32_t in_place =
      lanes_equal(ids, n, _mm_add_epi32(_mm_setr_epi32(0, 1, 2, 3), _mm_set1_epi32(first)), _mm_set1_epi32(4));
  if (valid_bits & ~in_place) return {};
  return {valid_bits << first, first};
}

// Leaves lane i of a packet out of Embree's walk. The valid mask says so
// where Embree walks 16 rays at once; below AVX-512 it hands a 16-ray packet
// to its ray-stream code, which drops the mask and walks every lane whose
// tnear <= tfar: on an AVX2 machine a packet's idle lanes, and the shadow
// rays its cache had answered, were walked too.
inline void disable_lane(RTCRay16& rays, int* valid, int i) {
  valid[i] = 0;
  rays.tnear[i] = __builtin_inff();
}

// Bit i set where tfar[i] < 0 (Embree's mark of an occluded ray), for 16
// floats: four SSE compares. Read one float at a time, right after Embree
// wrote them, they took 1.7% of gears' time (perf); this way gears renders
// in 0.99x the time.
inline uint32_t negative_lanes(const float* tfar) {
  uint32_t bits = 0;
  for (int q = 0; q < 4; ++q) {
    const __m128 four = _mm_loadu_ps(tfar + 4 * q);
    bits |= static_cast<uint32_t>(_mm_movemask_ps(_mm_cmplt_ps(four, _mm_setzero_ps()))) << (4 * q);
  }
  return bits;
}

}  // namespace rayfarm
