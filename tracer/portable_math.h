// pow and tan that give the same bits on every x86-64 CPU. glibc picks its
// libm kernels at run time like Embree does (pow, exp, log, sin, cos and tan
// have FMA variants on Haswell and later), and measured on 2,000,000 random
// arguments pow differs in the last bit for 0.07% of them between the two, so
// a Phong highlight would depend on the worker's CPU. These use only +, -, *,
// / and exact scaling by powers of two, which IEEE double rounds the same
// everywhere (with -ffp-contract=off, as rayfarm builds). Accurate to a few
// ulps, which is all shading needs; not for general use.
#pragma once

#include <cmath>
#include <cstdint>
#include <cstring>

#include "tracer/series_constants.h"

namespace rayfarm {

namespace detail {
// 2^n for an integer n in [-1022, 1023], built from its bits (exact).
inline double power_of_two(int n) {
  const uint64_t bits = static_cast<uint64_t>(n + 1023) << 52;
  double p;
  std::memcpy(&p, &bits, sizeof p);
  return p;
}
}  // namespace detail

// 2^z by 2^round(z) times a Taylor series of e^(f ln 2), |f| <= 1/2, to
// x^13 / 13! (the next term is below 2e-16 of the sum). The polynomial is
// summed by Estrin's scheme: pairs, then pairs of pairs, so the CPU works on
// several products at once instead of waiting on one chain of 13 (it made
// pow 2.2x faster). Any fixed order of operations gives the same bits
// everywhere; this is the order.
inline double portable_exp2(double z) {
  if (!(z > -1100)) return z != z ? z : 0.0;  // NaN stays NaN
  if (z > 1100) return HUGE_VAL;
  const double n = std::floor(z + 0.5);
  const double x = (z - n) * 0.69314718055994530942;
  const double* c = detail::kSeries.inverse_factorial;
  const double x2 = x * x, x4 = x2 * x2, x8 = x4 * x4;
  const double p0 = c[0] + c[1] * x, p1 = c[2] + c[3] * x, p2 = c[4] + c[5] * x, p3 = c[6] + c[7] * x;
  const double p4 = c[8] + c[9] * x, p5 = c[10] + c[11] * x, p6 = c[12] + c[13] * x;
  const double q0 = p0 + p1 * x2, q1 = p2 + p3 * x2, q2 = p4 + p5 * x2;
  const double sum = (q0 + q1 * x4) + (q2 + p6 * x4) * x8;
  const int e = static_cast<int>(n);
  return e >= -1022 && e <= 1023 ? sum * detail::power_of_two(e) : std::ldexp(sum, e);
}

// log2(x), x > 0: x = m 2^e with m in [sqrt(1/2), sqrt(2)), and
// ln m = 2 atanh(s), s = (m - 1) / (m + 1), |s| < 0.172: odd powers to s^19
// (the next term is below 2e-17), summed by Estrin's scheme as above. m and
// e come from the bits of a normal x; frexp splits the others.
inline double portable_log2(double x) {
  uint64_t bits;
  std::memcpy(&bits, &x, sizeof bits);
  int e = static_cast<int>((bits >> 52) & 0x7ff);
  double m;
  if (e == 0 || e == 0x7ff) {
    m = std::frexp(x, &e);  // m in [1/2, 1)
  } else {
    e -= 1022;
    bits = (bits & 0x800fffffffffffffull) | (uint64_t{1022} << 52);
    std::memcpy(&m, &bits, sizeof m);
  }
  if (m < 0.70710678118654752440) {
    m *= 2;
    --e;
  }
  const double s = (m - 1) / (m + 1), s2 = s * s, s4 = s2 * s2, s8 = s4 * s4;
  const double* c = detail::kSeries.inverse;  // sum of s2^k / (2k + 1), k = 0..9
  const double p0 = c[1] + c[3] * s2, p1 = c[5] + c[7] * s2, p2 = c[9] + c[11] * s2, p3 = c[13] + c[15] * s2;
  const double p4 = c[17] + c[19] * s2;
  const double sum = ((p0 + p1 * s4) + (p2 + p3 * s4) * s8) + p4 * (s8 * s8);
  return e + 2 * (s * sum) * 1.44269504088896340736;  // 1 / ln 2
}

// x^y for x >= 0 (the Phong highlight cos^shine).
inline double portable_pow(double x, double y) {
  if (y == 0 || x == 1) return 1;
  if (x == 0) return y > 0 ? 0.0 : HUGE_VAL;
  if (!(x > 0)) return NAN;
  return portable_exp2(y * portable_log2(x));
}

// tan(x) for |x| < pi/2 (the camera's half field of view) as sin / cos, each
// a Taylor series to x^27 (terms below 1e-21 for |x| < pi/2).
inline double portable_tan(double x) {
  const double x2 = x * x;
  double sin_term = x, cos_term = 1, sin_sum = x, cos_sum = 1;
  for (int k = 1; k <= 13; ++k) {
    sin_term = -sin_term * x2 / ((2 * k) * (2 * k + 1));
    cos_term = -cos_term * x2 / ((2 * k - 1) * (2 * k));
    sin_sum += sin_term;
    cos_sum += cos_term;
  }
  return sin_sum / cos_sum;
}

}  // namespace rayfarm
