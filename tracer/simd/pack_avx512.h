// Eight doubles in an AVX-512 register, comparisons in mask registers, for the
// lane kernels (fill_lanes.h, triangle_lanes.h, sphere_lanes.h, cone_lanes.h,
// hit_frame_lanes.h, pow_lanes.h, phong_lanes.h). Comparisons are C++'s:
// false for NaN, except != (true).
#pragma once

#include <immintrin.h>

#include <cstdint>

#include "tracer/simd/double_bits.h"

namespace rayfarm::simd {
namespace {

struct Pack {
  using D = __m512d;
  using M = __mmask8;
  static constexpr int kWidth = 8;
  static D load(const double* p) { return _mm512_load_pd(p); }
  static void store(double* p, D x) { _mm512_store_pd(p, x); }
  static D set1(double x) { return _mm512_set1_pd(x); }
  static M lt(D a, D b) { return _mm512_cmp_pd_mask(a, b, _CMP_LT_OQ); }
  static M gt(D a, D b) { return _mm512_cmp_pd_mask(a, b, _CMP_GT_OQ); }
  static M ne(D a, D b) { return _mm512_cmp_pd_mask(a, b, _CMP_NEQ_UQ); }
  static M ge(D a, D b) { return _mm512_cmp_pd_mask(a, b, _CMP_GE_OQ); }
  static M eq(D a, D b) { return _mm512_cmp_pd_mask(a, b, _CMP_EQ_OQ); }
  static M and_(M a, M b) { return static_cast<M>(a & b); }
  static M or_(M a, M b) { return static_cast<M>(a | b); }
  static M andnot(M a, M b) { return static_cast<M>(~a & b); }  // !a && b
  static uint32_t bits(M m) { return m; }
  static D select(M m, D if_set, D if_clear) { return _mm512_mask_blend_pd(m, if_clear, if_set); }
  static D sqrt(D x) { return _mm512_sqrt_pd(x); }
  static D floor(D x) { return _mm512_roundscale_pd(x, _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC); }
  // As in pack_sse2.h.
  static D exponent_field(D x) {
    const __m512i field =
        _mm512_and_si512(_mm512_srli_epi64(_mm512_castpd_si512(x), 52), _mm512_set1_epi64(0x7ff));
    return _mm512_sub_pd(_mm512_castsi512_pd(_mm512_or_si512(field, _mm512_set1_epi64(kTwo52Bits))),
                         _mm512_set1_pd(kTwo52));
  }
  static D with_exponent_field(D x, int field) {
    const __m512i kept = _mm512_and_si512(_mm512_castpd_si512(x), _mm512_set1_epi64(kSignAndMantissa));
    return _mm512_castsi512_pd(_mm512_or_si512(kept, _mm512_set1_epi64(static_cast<long long>(field) << 52)));
  }
  static D power_of_two(D n) {
    return _mm512_castsi512_pd(
        _mm512_slli_epi64(_mm512_castpd_si512(_mm512_add_pd(n, _mm512_set1_pd(kTwo52 + 1023))), 52));
  }
  // x rounded to float (stored at f[0..7], 32-byte aligned) and back, as in
  // pack_sse2.h.
  static D round_to_float(D x, float* f) {
    __m256 r = _mm512_cvtpd_ps(x);
    asm("" : "+v"(r));
    _mm256_store_ps(f, r);
    return _mm512_cvtps_pd(r);
  }
  // |magnitude| with the sign of `sign`, as std::copysign (AVX-512F has no
  // floating-point and/or: integer ones on the same bits).
  static D copysign(D magnitude, D sign) {
    const __m512i sign_bit = _mm512_set1_epi64(static_cast<long long>(0x8000000000000000ull));
    const __m512i m = _mm512_andnot_si512(sign_bit, _mm512_castpd_si512(magnitude));
    const __m512i s = _mm512_and_si512(sign_bit, _mm512_castpd_si512(sign));
    return _mm512_castsi512_pd(_mm512_or_si512(m, s));
  }
  static D neg(D x) {  // as unary minus: -0 for 0
    const __m512i sign_bit = _mm512_set1_epi64(static_cast<long long>(0x8000000000000000ull));
    return _mm512_castsi512_pd(_mm512_xor_si512(sign_bit, _mm512_castpd_si512(x)));
  }
  // offset_component() (tracer/ray_offset.h) of p and n, each rounded to
  // float, with the float of `scale`, eight lanes in AVX registers (as
  // offset_sse.h does four); the result back in double.
  static D offset(D p_wide, D n_wide, D scale_wide) {
    const __m256 p = _mm512_cvtpd_ps(p_wide), n = _mm512_cvtpd_ps(n_wide);
    const __m256 scale = _mm512_cvtpd_ps(scale_wide);
    const __m256 magnitude = _mm256_and_ps(p, _mm256_castsi256_ps(_mm256_set1_epi32(0x7fffffff)));
    const __m256 origin_zone = _mm256_mul_ps(_mm256_set1_ps(1.0f / 32.0f), scale);
    const __m256 near = _mm256_cmp_ps(magnitude, origin_zone, _CMP_LT_OQ);
    const __m256 float_offset =
        _mm256_add_ps(p, _mm256_mul_ps(_mm256_mul_ps(_mm256_set1_ps(1.0f / 65536.0f), scale), n));
    const __m256i of_i = _mm256_cvttps_epi32(_mm256_mul_ps(_mm256_set1_ps(256.0f), n));
    const __m256i negative = _mm256_castps_si256(_mm256_cmp_ps(p, _mm256_setzero_ps(), _CMP_LT_OQ));
    const __m256i step = _mm256_sub_epi32(_mm256_xor_si256(of_i, negative), negative);
    const __m256 int_offset = _mm256_castsi256_ps(_mm256_add_epi32(_mm256_castps_si256(p), step));
    return _mm512_cvtps_pd(_mm256_blendv_ps(int_offset, float_offset, near));
  }
};

}  // namespace
}  // namespace rayfarm::simd
