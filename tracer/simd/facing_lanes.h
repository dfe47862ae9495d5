// The facing kernel (tracer/lane_kernels.h) over a Pack of W doubles
// (pack_*.h): light_in_front() of tracer/phong.h for W points at a time,
// its products and sums in the scalar code's order. Included only by the
// kernels_*.cpp units.
#pragma once

#include <cstdint>

#include "tracer/lane_kernels.h"

namespace rayfarm::simd {
namespace {

template <class P>
uint32_t facing_lanes(const double (*p)[HitLanes::kLanes], const double (*ns)[HitLanes::kLanes], const double* light,
                      int count) {
  using D = typename P::D;
  constexpr int kW = P::kWidth;
  const D zero = P::set1(0.0);
  const D lx = P::set1(light[0]), ly = P::set1(light[1]), lz = P::set1(light[2]);
  uint32_t bits = 0;
  for (int first = 0; first < count; first += kW) {
    const D d = P::load(ns[0] + first) * (lx - P::load(p[0] + first)) +
                P::load(ns[1] + first) * (ly - P::load(p[1] + first)) +
                P::load(ns[2] + first) * (lz - P::load(p[2] + first));
    bits |= P::bits(P::gt(d, zero)) << first;
  }
  return bits & ((1u << count) - 1);
}

}  // namespace
}  // namespace rayfarm::simd
