// The fill kernel (tracer/lane_kernels.h) over a Pack of W doubles (pack_*.h):
// a packet's rays rounded to float and back, with ShearedRay's axes and shear
// (tracer/shapes.h), W rays at a time. Its branches become selects; the
// rounding, the division and the products are the scalar code's, correctly
// rounded alike at every width. Included only by the kernels_*.cpp units.
#pragma once

#include <cstdint>

#include "tracer/lane_kernels.h"

namespace rayfarm::simd {
namespace {

template <class P>
bool fill_lanes(const double* orgs, const double* dirs, int count, double tfar, RayLanes& r, FloatLanes& f) {
  using D = typename P::D;
  constexpr int kW = P::kWidth;
  constexpr int kLanes = RayLanes::kLanes;
  for (int i = 0; i < count; ++i) {  // AoS in, SoA out
    for (int c = 0; c < 3; ++c) {
      r.org[c][i] = orgs[3 * i + c];
      r.dir[c][i] = dirs[3 * i + c];
    }
  }
  for (int i = count; i < kLanes; ++i) {  // disabled lanes repeat ray 0
    for (int c = 0; c < 3; ++c) {
      r.org[c][i] = orgs[c];
      r.dir[c][i] = dirs[c];
    }
  }
  for (int i = 0; i < kLanes; ++i) r.tfar[i] = tfar;
  const D zero = P::set1(0.0), one = P::set1(1.0), limit = P::set1(kMaxRayComponent);
  uint32_t z_is_x = 0, z_is_y = 0, flipped = 0, out_of_range = 0;
  constexpr uint32_t kGroup = (1u << kW) - 1;
  for (int first = 0; first < kLanes; first += kW) {
    D d[3];
    for (int c = 0; c < 3; ++c) {
      const D o = P::load(r.org[c] + first), unrounded = P::load(r.dir[c] + first);
      // limit >= |x| is false for NaN, as check_ray()'s test.
      out_of_range |= kGroup & ~P::bits(P::and_(P::ge(limit, P::copysign(o, zero)),
                                                P::ge(limit, P::copysign(unrounded, zero))));
      P::store(r.org[c] + first, P::round_to_float(o, f.org[c] + first));
      d[c] = P::round_to_float(unrounded, f.dir[c] + first);
      P::store(r.dir[c] + first, d[c]);
    }
    // ShearedRay: kz = ax > ay ? (ax > az ? 0 : 2) : (ay > az ? 1 : 2), then
    // (kx, ky) = (1, 2), (2, 0) or (0, 1), swapped when d[kz] < 0.
    const D ax = P::copysign(d[0], zero), ay = P::copysign(d[1], zero), az = P::copysign(d[2], zero);
    const auto xy = P::gt(ax, ay);
    const auto zx = P::and_(xy, P::gt(ax, az)), zy = P::andnot(xy, P::gt(ay, az));
    const D dz = P::select(zx, d[0], P::select(zy, d[1], d[2]));
    const D dkx = P::select(zx, d[1], P::select(zy, d[2], d[0]));
    const D dky = P::select(zx, d[2], P::select(zy, d[0], d[1]));
    const auto neg = P::lt(dz, zero);
    const D sz = one / dz;
    P::store(r.sz + first, sz);
    P::store(r.sx + first, P::select(neg, dky, dkx) * sz);
    P::store(r.sy + first, P::select(neg, dkx, dky) * sz);
    z_is_x |= P::bits(zx) << first;
    z_is_y |= P::bits(zy) << first;
    flipped |= P::bits(neg) << first;
  }
  r.z_is_x = z_is_x, r.z_is_y = z_is_y, r.flipped = flipped;
  return out_of_range == 0;
}

}  // namespace
}  // namespace rayfarm::simd
