// Two doubles in an SSE2 register, for the lane kernels (fill_lanes.h,
// triangle_lanes.h, sphere_lanes.h, cone_lanes.h, hit_frame_lanes.h,
// pow_lanes.h, phong_lanes.h).
// Comparisons are C++'s: false for NaN, except != (true).
#pragma once

#include <emmintrin.h>

#include <cstdint>

#include "tracer/simd/double_bits.h"
#include "tracer/simd/offset_sse.h"

namespace rayfarm::simd {
namespace {

struct Pack {
  using D = __m128d;
  using M = __m128d;
  static constexpr int kWidth = 2;
  static D load(const double* p) { return _mm_load_pd(p); }
  static void store(double* p, D x) { _mm_store_pd(p, x); }
  static D set1(double x) { return _mm_set1_pd(x); }
  static M lt(D a, D b) { return _mm_cmplt_pd(a, b); }
  static M gt(D a, D b) { return _mm_cmpgt_pd(a, b); }
  static M ne(D a, D b) { return _mm_cmpneq_pd(a, b); }
  static M ge(D a, D b) { return _mm_cmpge_pd(a, b); }
  static M eq(D a, D b) { return _mm_cmpeq_pd(a, b); }
  static M and_(M a, M b) { return _mm_and_pd(a, b); }
  static M or_(M a, M b) { return _mm_or_pd(a, b); }
  static M andnot(M a, M b) { return _mm_andnot_pd(a, b); }  // !a && b
  static uint32_t bits(M m) { return static_cast<uint32_t>(_mm_movemask_pd(m)); }
  static D select(M m, D if_set, D if_clear) { return _mm_or_pd(_mm_and_pd(m, if_set), _mm_andnot_pd(m, if_clear)); }
  static D sqrt(D x) { return _mm_sqrt_pd(x); }
  // std::floor for |x| < 2^31 (-0 excepted: +0); beyond, -2^31 (SSE2 has no
  // rounding to integers in double: truncation through int32, then a step
  // down where that went up).
  static D floor(D x) {
    const D t = _mm_cvtepi32_pd(_mm_cvttpd_epi32(x));
    return _mm_sub_pd(t, _mm_and_pd(_mm_cmpgt_pd(t, x), _mm_set1_pd(1.0)));
  }
  // The biased exponent field of x (bits 52..62), as a double.
  static D exponent_field(D x) {
    const __m128i field = _mm_and_si128(_mm_srli_epi64(_mm_castpd_si128(x), 52), _mm_set1_epi64x(0x7ff));
    return _mm_sub_pd(_mm_castsi128_pd(_mm_or_si128(field, _mm_set1_epi64x(kTwo52Bits))), _mm_set1_pd(kTwo52));
  }
  // x with its exponent field replaced by `field` (sign and mantissa kept).
  static D with_exponent_field(D x, int field) {
    const __m128i kept = _mm_and_si128(_mm_castpd_si128(x), _mm_set1_epi64x(kSignAndMantissa));
    return _mm_castsi128_pd(_mm_or_si128(kept, _mm_set1_epi64x(static_cast<long long>(field) << 52)));
  }
  // 2^n for integral n in [-1022, 1023], from its bits (exact): n + 1023 is
  // the low mantissa bits of n + 2^52 + 1023, shifted into the exponent field.
  static D power_of_two(D n) {
    return _mm_castsi128_pd(_mm_slli_epi64(_mm_castpd_si128(_mm_add_pd(n, _mm_set1_pd(kTwo52 + 1023))), 52));
  }
  // x rounded to float (stored at f[0..1]) and back. The empty asm keeps the
  // optimiser from folding the round trip away (see to_float() in
  // embree_scene.cpp).
  static D round_to_float(D x, float* f) {
    __m128 r = _mm_cvtpd_ps(x);
    asm("" : "+x"(r));
    _mm_storel_pi(reinterpret_cast<__m64*>(f), r);
    return _mm_cvtps_pd(r);
  }
  // |magnitude| with the sign of `sign`, as std::copysign.
  static D copysign(D magnitude, D sign) {
    const D sign_bit = _mm_set1_pd(-0.0);
    return _mm_or_pd(_mm_andnot_pd(sign_bit, magnitude), _mm_and_pd(sign_bit, sign));
  }
  static D neg(D x) { return _mm_xor_pd(x, _mm_set1_pd(-0.0)); }  // as unary minus: -0 for 0
  // offset_component() (tracer/ray_offset.h) of p and n, each rounded to
  // float, with the float of `scale`; the result back in double.
  static D offset(D p, D n, D scale) {
    return _mm_cvtps_pd(offset_floats(_mm_cvtpd_ps(p), _mm_cvtpd_ps(n), _mm_cvtpd_ps(scale)));
  }
};

}  // namespace
}  // namespace rayfarm::simd
