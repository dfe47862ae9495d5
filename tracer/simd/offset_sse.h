// offset_component() of tracer/ray_offset.h on four floats in an SSE2
// register: both of its branches are taken, the lane picks its own. For the
// 2- and 4-wide packs (pack_sse2.h, pack_avx2.h).
#pragma once

#include <emmintrin.h>

namespace rayfarm::simd {
namespace {

inline __m128 offset_floats(__m128 p, __m128 n, __m128 scale) {
  const __m128 magnitude = _mm_and_ps(p, _mm_castsi128_ps(_mm_set1_epi32(0x7fffffff)));
  const __m128 near = _mm_cmplt_ps(magnitude, _mm_mul_ps(_mm_set1_ps(1.0f / 32.0f), scale));
  const __m128 float_offset = _mm_add_ps(p, _mm_mul_ps(_mm_mul_ps(_mm_set1_ps(1.0f / 65536.0f), scale), n));
  const __m128i of_i = _mm_cvttps_epi32(_mm_mul_ps(_mm_set1_ps(256.0f), n));
  // (p < 0) ? -of_i : of_i, as (of_i ^ m) - m with m all ones where p < 0.
  const __m128i negative = _mm_castps_si128(_mm_cmplt_ps(p, _mm_setzero_ps()));
  const __m128i step = _mm_sub_epi32(_mm_xor_si128(of_i, negative), negative);
  const __m128 int_offset = _mm_castsi128_ps(_mm_add_epi32(_mm_castps_si128(p), step));
  return _mm_or_ps(_mm_and_ps(near, float_offset), _mm_andnot_ps(near, int_offset));
}

}  // namespace
}  // namespace rayfarm::simd
