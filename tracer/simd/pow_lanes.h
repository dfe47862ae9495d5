// portable_pow() (tracer/portable_math.h) over a Pack of W doubles
// (pack_*.h), for the Phong kernel (phong_lanes.h): the scalar code's
// operations in its order, so its bits, in every lane whose arguments keep
// to the common path. Lanes that leave it -- x not a positive normal
// number, or x^y near or beyond the ends of the normal range, where the
// scalar code falls back on frexp or ldexp -- are flagged for the scalar
// code instead. Included only by the kernels_*.cpp units.
#pragma once

#include "tracer/series_constants.h"

namespace rayfarm::simd {
namespace {

// portable_log2(x), and in `usable` the lanes where x is a positive normal
// number (the others take frexp there).
template <class P>
typename P::D log2_lanes(typename P::D x, typename P::M& usable) {
  using D = typename P::D;
  const D field = P::exponent_field(x);
  usable = P::and_(P::gt(x, P::set1(0.0)), P::and_(P::gt(field, P::set1(0.0)), P::lt(field, P::set1(2047.0))));
  D e = field - P::set1(1022.0);
  D m = P::with_exponent_field(x, 1022);  // in [1/2, 1)
  const auto low = P::lt(m, P::set1(0.70710678118654752440));
  m = P::select(low, m * P::set1(2.0), m);
  e = P::select(low, e - P::set1(1.0), e);
  const D s = (m - P::set1(1.0)) / (m + P::set1(1.0)), s2 = s * s, s4 = s2 * s2, s8 = s4 * s4;
  const double* c = detail::kSeries.inverse;
  auto pair = [&](int a, int b) { return P::set1(c[a]) + P::set1(c[b]) * s2; };
  const D p0 = pair(1, 3), p1 = pair(5, 7), p2 = pair(9, 11), p3 = pair(13, 15), p4 = pair(17, 19);
  const D sum = ((p0 + p1 * s4) + (p2 + p3 * s4) * s8) + p4 * (s8 * s8);
  return e + P::set1(2.0) * (s * sum) * P::set1(1.44269504088896340736);
}

// portable_exp2(z), and in `usable` the lanes where round(z) is in
// [-1022, 1023], or z <= -1100 (0, as there: a highlight's power often
// underflows); the others take the scalar code's other early returns or
// ldexp.
template <class P>
typename P::D exp2_lanes(typename P::D z, typename P::M& usable) {
  using D = typename P::D;
  D n = P::floor(z + P::set1(0.5));
  usable = P::and_(P::ge(n, P::set1(-1022.0)), P::ge(P::set1(1023.0), n));
  const auto underflow = P::ge(P::set1(-1100.0), z);
  n = P::select(usable, n, P::set1(0.0));  // keeps power_of_two() in range
  const D x = (z - n) * P::set1(0.69314718055994530942);
  const double* c = detail::kSeries.inverse_factorial;
  auto pair = [&](int a) { return P::set1(c[a]) + P::set1(c[a + 1]) * x; };
  const D x2 = x * x, x4 = x2 * x2, x8 = x4 * x4;
  const D p0 = pair(0), p1 = pair(2), p2 = pair(4), p3 = pair(6), p4 = pair(8), p5 = pair(10), p6 = pair(12);
  const D q0 = p0 + p1 * x2, q1 = p2 + p3 * x2, q2 = p4 + p5 * x2;
  const D sum = (q0 + q1 * x4) + (q2 + p6 * x4) * x8;
  usable = P::or_(usable, underflow);
  return P::select(underflow, P::set1(0.0), sum * P::power_of_two(n));
}

// portable_pow(x, y), and in `usable` the lanes it holds for.
template <class P>
typename P::D pow_lanes(typename P::D x, typename P::D y, typename P::M& usable) {
  typename P::M log_usable, exp_usable;
  const typename P::D power = exp2_lanes<P>(y * log2_lanes<P>(x, log_usable), exp_usable);
  const auto one = P::or_(P::eq(y, P::set1(0.0)), P::eq(x, P::set1(1.0)));
  usable = P::or_(one, P::and_(log_usable, exp_usable));
  return P::select(one, P::set1(1.0), power);
}

}  // namespace
}  // namespace rayfarm::simd
