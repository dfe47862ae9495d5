// The hit-frame kernel (tracer/lane_kernels.h) over a Pack of W doubles
// (pack_*.h): hit_frame() (tracer/hit_frame.h) for W hits at a time. Its
// branches become selects; the square roots, divisions, products and float
// roundings are the scalar code's, in its order, correctly rounded alike at
// every width. Included only by the kernels_*.cpp units.
#pragma once

#include "tracer/lane_kernels.h"

namespace rayfarm::simd {
namespace {

// unit_or(v, fallback): v * (1 / |v|) where |v|^2 is positive and finite.
template <class P>
void unit_or_lanes(const typename P::D v[3], const typename P::D fallback[3], typename P::D out[3]) {
  using D = typename P::D;
  const D len2 = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
  const auto usable = P::and_(P::gt(len2, P::set1(0.0)), P::lt(len2, P::set1(__builtin_huge_val())));
  const D inverse = P::set1(1.0) / P::sqrt(len2);
  for (int c = 0; c < 3; ++c) out[c] = P::select(usable, v[c] * inverse, fallback[c]);
}

template <class P>
void hit_frame_lanes(HitLanes& h, int count) {
  using D = typename P::D;
  constexpr int kW = P::kWidth;
  const D zero = P::set1(0.0);
  uint32_t entering = 0;
  for (int first = 0; first < count; first += kW) {
    D org[3], dir[3], ng[3];
    for (int c = 0; c < 3; ++c) {
      org[c] = P::load(h.org[c] + first);
      dir[c] = P::load(h.dir[c] + first);
      ng[c] = P::load(h.ng[c] + first);
    }
    const D t = P::load(h.t + first);
    const D up[3] = {zero, zero, P::set1(1.0)};
    D d[3], n[3];
    unit_or_lanes<P>(dir, up, d);
    const D back[3] = {P::neg(d[0]), P::neg(d[1]), P::neg(d[2])};
    unit_or_lanes<P>(ng, back, n);
    const auto in = P::lt(d[0] * n[0] + d[1] * n[1] + d[2] * n[2], zero);
    entering |= P::bits(in) << first;
    // offset_scale(): the largest |coordinate| of p and org, at least 1e-30;
    // a > m ? a : m, so a NaN coordinate is passed over as there.
    D p[3], nf[3];
    D scale = P::set1(1e-30);
    for (int c = 0; c < 3; ++c) {
      nf[c] = P::select(in, n[c], P::neg(n[c]));
      p[c] = org[c] + dir[c] * t;
      const D a = P::copysign(p[c], zero);
      scale = P::select(P::gt(a, scale), a, scale);
    }
    for (int c = 0; c < 3; ++c) {
      const D a = P::copysign(org[c], zero);
      scale = P::select(P::gt(a, scale), a, scale);
    }
    for (int c = 0; c < 3; ++c) {
      P::store(h.d[c] + first, d[c]);
      P::store(h.nf[c] + first, nf[c]);
      P::store(h.p[c] + first, p[c]);
      P::store(h.p_front[c] + first, P::offset(p[c], nf[c], scale));
      P::store(h.p_back[c] + first, P::offset(p[c], P::neg(nf[c]), scale));
    }
  }
  h.entering = entering;
}

}  // namespace
}  // namespace rayfarm::simd
