// The triangle lane kernel (tracer/lane_kernels.h) over a Pack of W doubles
// (pack_*.h): intersect_triangle() of tracer/shapes.h, operation for
// operation, on W rays at a time. Included only by the kernels_*.cpp units.
#pragma once

#include <cstdint>

#include "tracer/lane_kernels.h"

namespace rayfarm::simd {
namespace {

template <class P>
uint32_t triangle_lanes(const RayLanes& r, const AxisClass& axes, const double* a, const double* b, const double* c,
                        TriangleLaneHits& out) {
  const int kx = axes.kx, ky = axes.ky, kz = axes.kz;
  const uint32_t active = axes.lanes;
  using D = typename P::D;
  constexpr int kW = P::kWidth;
  constexpr uint32_t kGroup = (1u << kW) - 1;
  const D zero = P::set1(0.0);
  const D a_x = P::set1(a[kx]), a_y = P::set1(a[ky]), a_z = P::set1(a[kz]);
  const D b_x = P::set1(b[kx]), b_y = P::set1(b[ky]), b_z = P::set1(b[kz]);
  const D c_x = P::set1(c[kx]), c_y = P::set1(c[ky]), c_z = P::set1(c[kz]);
  uint32_t hits = 0;
  for (int first = 0; first < RayLanes::kLanes; first += kW) {
    const uint32_t lanes = (active >> first) & kGroup;
    if (!lanes) continue;
    const D ox = P::load(r.org[kx] + first), oy = P::load(r.org[ky] + first), oz = P::load(r.org[kz] + first);
    const D sx = P::load(r.sx + first), sy = P::load(r.sy + first);
    // The vertices relative to the origin, sheared (A = a - org, ax = A[kx] - sx * az, ...).
    const D az = a_z - oz, bz = b_z - oz, cz = c_z - oz;
    const D ax = (a_x - ox) - sx * az, ay = (a_y - oy) - sy * az;
    const D bx = (b_x - ox) - sx * bz, by = (b_y - oy) - sy * bz;
    const D cx = (c_x - ox) - sx * cz, cy = (c_y - oy) - sy * cz;
    const D u = cx * by - cy * bx;  // weight of a
    const D v = ax * cy - ay * cx;  // weight of b
    const D w = bx * ay - by * ax;  // weight of c
    // Mixed signs miss: most candidates, which then cost no division.
    const auto negative = P::or_(P::or_(P::lt(u, zero), P::lt(v, zero)), P::lt(w, zero));
    const auto positive = P::or_(P::or_(P::gt(u, zero), P::gt(v, zero)), P::gt(w, zero));
    const uint32_t inside = lanes & ~P::bits(P::and_(negative, positive));
    if (!inside) continue;
    const D sz = P::load(r.sz + first);
    const D det = u + v + w;
    const D tz = u * (sz * az) + v * (sz * bz) + w * (sz * cz);
    const D t = tz / det;  // det == 0 lanes miss below (the quotient is inf or NaN, never a trap)
    const auto in_range = P::and_(P::and_(P::ne(det, zero), P::gt(t, zero)), P::lt(t, P::load(r.tfar + first)));
    const uint32_t hit = inside & P::bits(in_range);
    if (!hit) continue;
    P::store(out.t + first, t);
    P::store(out.v + first, v);
    P::store(out.w + first, w);
    P::store(out.det + first, det);
    hits |= hit << first;
  }
  return hits;
}

}  // namespace
}  // namespace rayfarm::simd
