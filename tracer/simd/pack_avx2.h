// Four doubles in an AVX register, for the lane kernels (fill_lanes.h,
// triangle_lanes.h, sphere_lanes.h, cone_lanes.h, hit_frame_lanes.h,
// pow_lanes.h, phong_lanes.h).
// Comparisons are C++'s: false for NaN, except != (true).
#pragma once

#include <immintrin.h>

#include <cstdint>

#include "tracer/simd/double_bits.h"
#include "tracer/simd/offset_sse.h"

namespace rayfarm::simd {
namespace {

struct Pack {
  using D = __m256d;
  using M = __m256d;
  static constexpr int kWidth = 4;
  static D load(const double* p) { return _mm256_load_pd(p); }
  static void store(double* p, D x) { _mm256_store_pd(p, x); }
  static D set1(double x) { return _mm256_set1_pd(x); }
  static M lt(D a, D b) { return _mm256_cmp_pd(a, b, _CMP_LT_OQ); }
  static M gt(D a, D b) { return _mm256_cmp_pd(a, b, _CMP_GT_OQ); }
  static M ne(D a, D b) { return _mm256_cmp_pd(a, b, _CMP_NEQ_UQ); }
  static M ge(D a, D b) { return _mm256_cmp_pd(a, b, _CMP_GE_OQ); }
  static M eq(D a, D b) { return _mm256_cmp_pd(a, b, _CMP_EQ_OQ); }
  static M and_(M a, M b) { return _mm256_and_pd(a, b); }
  static M or_(M a, M b) { return _mm256_or_pd(a, b); }
  static M andnot(M a, M b) { return _mm256_andnot_pd(a, b); }  // !a && b
  static uint32_t bits(M m) { return static_cast<uint32_t>(_mm256_movemask_pd(m)); }
  static D select(M m, D if_set, D if_clear) { return _mm256_blendv_pd(if_clear, if_set, m); }
  static D sqrt(D x) { return _mm256_sqrt_pd(x); }
  static D floor(D x) { return _mm256_floor_pd(x); }
  // As in pack_sse2.h.
  static D exponent_field(D x) {
    const __m256i field =
        _mm256_and_si256(_mm256_srli_epi64(_mm256_castpd_si256(x), 52), _mm256_set1_epi64x(0x7ff));
    return _mm256_sub_pd(_mm256_castsi256_pd(_mm256_or_si256(field, _mm256_set1_epi64x(kTwo52Bits))),
                         _mm256_set1_pd(kTwo52));
  }
  static D with_exponent_field(D x, int field) {
    const __m256i kept = _mm256_and_si256(_mm256_castpd_si256(x), _mm256_set1_epi64x(kSignAndMantissa));
    return _mm256_castsi256_pd(_mm256_or_si256(kept, _mm256_set1_epi64x(static_cast<long long>(field) << 52)));
  }
  static D power_of_two(D n) {
    return _mm256_castsi256_pd(
        _mm256_slli_epi64(_mm256_castpd_si256(_mm256_add_pd(n, _mm256_set1_pd(kTwo52 + 1023))), 52));
  }
  // x rounded to float (stored at f[0..3], 16-byte aligned) and back, as in
  // pack_sse2.h.
  static D round_to_float(D x, float* f) {
    __m128 r = _mm256_cvtpd_ps(x);
    asm("" : "+x"(r));
    _mm_store_ps(f, r);
    return _mm256_cvtps_pd(r);
  }
  // |magnitude| with the sign of `sign`, as std::copysign.
  static D copysign(D magnitude, D sign) {
    const D sign_bit = _mm256_set1_pd(-0.0);
    return _mm256_or_pd(_mm256_andnot_pd(sign_bit, magnitude), _mm256_and_pd(sign_bit, sign));
  }
  static D neg(D x) { return _mm256_xor_pd(x, _mm256_set1_pd(-0.0)); }  // as unary minus: -0 for 0
  // offset_component() (tracer/ray_offset.h) of p and n, each rounded to
  // float, with the float of `scale`; the result back in double.
  static D offset(D p, D n, D scale) {
    return _mm256_cvtps_pd(offset_floats(_mm256_cvtpd_ps(p), _mm256_cvtpd_ps(n), _mm256_cvtpd_ps(scale)));
  }
};

}  // namespace
}  // namespace rayfarm::simd
