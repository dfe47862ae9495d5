// The Phong kernel (tracer/lane_kernels.h) over a Pack of W doubles
// (pack_*.h): phong_terms() (tracer/phong.h) for W lit hits at a time, its
// square root, divisions and highlight power (pow_lanes.h) in the scalar
// code's order. Included only by the kernels_*.cpp units.
#pragma once

#include "tracer/lane_kernels.h"
#include "tracer/simd/pow_lanes.h"

namespace rayfarm::simd {
namespace {

template <class P>
void phong_lanes(PhongLanes& h, int count) {
  using D = typename P::D;
  constexpr int kW = P::kWidth;
  const D zero = P::set1(0.0);
  uint32_t highlit = 0, scalar = 0;
  for (int first = 0; first < count; first += kW) {
    D l[3], ns[3], d[3];
    for (int c = 0; c < 3; ++c) {
      l[c] = P::load(h.to_light[c] + first);
      ns[c] = P::load(h.ns[c] + first);
      d[c] = P::load(h.d[c] + first);
    }
    const D ks = P::load(h.ks + first), shine = P::load(h.shine + first);
    const D dist = P::sqrt(l[0] * l[0] + l[1] * l[1] + l[2] * l[2]);
    const D n_dot_l = (ns[0] * l[0] + ns[1] * l[1] + ns[2] * l[2]) / dist;
    P::store(h.n_dot_l + first, n_dot_l);
    const D twice = P::set1(2.0) * n_dot_l, inverse = P::set1(1.0) / dist;
    D r[3];
    for (int c = 0; c < 3; ++c) r[c] = ns[c] * twice - l[c] * inverse;
    const D r_dot_v = P::neg(r[0] * d[0] + r[1] * d[1] + r[2] * d[2]);
    const auto lit = P::and_(P::gt(ks, zero), P::gt(r_dot_v, zero));
    const uint32_t lit_bits = P::bits(lit);
    if (!lit_bits) continue;  // most materials have no highlight: no power to take
    typename P::M usable;
    P::store(h.highlight + first, ks * pow_lanes<P>(r_dot_v, shine, usable));
    highlit |= lit_bits << first;
    scalar |= (lit_bits & ~P::bits(usable)) << first;
  }
  const uint32_t lanes = (1u << count) - 1;  // count <= 16; the lanes after it hold stale inputs
  h.highlit = highlit & lanes;
  h.scalar = scalar & lanes;
}

}  // namespace
}  // namespace rayfarm::simd
