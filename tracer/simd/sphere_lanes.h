// The sphere lane kernel (tracer/lane_kernels.h) over a Pack of W doubles
// (pack_*.h): intersect_sphere() of tracer/shapes.h, operation for operation,
// on W rays at a time, its branches turned into selects. Included only by the
// kernels_*.cpp units.
#pragma once

#include <cstdint>

#include "tracer/lane_kernels.h"

namespace rayfarm::simd {
namespace {

template <class P>
uint32_t sphere_lanes(const RayLanes& r, uint32_t active, const double* center, double radius, double* t_out) {
  using D = typename P::D;
  constexpr int kW = P::kWidth;
  constexpr uint32_t kGroup = (1u << kW) - 1;
  const D zero = P::set1(0.0);
  const D cx = P::set1(center[0]), cy = P::set1(center[1]), cz = P::set1(center[2]);
  const D r2 = P::set1(radius * radius);
  uint32_t hits = 0;
  for (int first = 0; first < RayLanes::kLanes; first += kW) {
    const uint32_t lanes = (active >> first) & kGroup;
    if (!lanes) continue;
    const D dx = P::load(r.dir[0] + first), dy = P::load(r.dir[1] + first), dz = P::load(r.dir[2] + first);
    const D fx = P::load(r.org[0] + first) - cx, fy = P::load(r.org[1] + first) - cy,
            fz = P::load(r.org[2] + first) - cz;  // f = o - center
    const D a = dx * dx + dy * dy + dz * dz;
    const D gx = fy * dz - fz * dy, gy = fz * dx - fx * dz, gz = fx * dy - fy * dx;  // f x d
    const D disc = r2 * a - (gx * gx + gy * gy + gz * gz);
    const uint32_t meets = lanes & P::bits(P::and_(P::ge(disc, zero), P::gt(a, zero)));
    if (!meets) continue;  // most candidates: no square root, no division
    const D b = -(fx * dx + fy * dy + fz * dz);
    const D c = (fx * fx + fy * fy + fz * fz) - r2;
    const D q = b + P::copysign(P::sqrt(disc), b);
    const D t0 = P::select(P::ne(q, zero), c / q, zero), t1 = q / a;
    const auto swap = P::gt(t0, t1);
    const D near = P::select(swap, t1, t0), far = P::select(swap, t0, t1);
    const D tfar = P::load(r.tfar + first);
    const auto near_ok = P::and_(P::gt(near, zero), P::lt(near, tfar));
    const auto far_ok = P::and_(P::gt(far, zero), P::lt(far, tfar));
    const uint32_t hit = meets & P::bits(P::or_(near_ok, far_ok));
    if (!hit) continue;
    P::store(t_out + first, P::select(near_ok, near, far));
    hits |= hit << first;
  }
  return hits;
}

}  // namespace
}  // namespace rayfarm::simd
