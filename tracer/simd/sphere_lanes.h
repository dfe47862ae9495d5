// The sphere lane kernel (tracer/lane_kernels.h) over a Pack of W doubles
// (pack_*.h): intersect_sphere() of tracer/shapes.h, operation for operation,
// on W rays at a time, its branches turned into selects. One sphere for every
// lane (sphere_lanes()), or each lane its own (sphere_lanes_per_lane()): the
// same operations on the same values either way. Included only by the
// kernels_*.cpp units.
#pragma once

#include <cstdint>

#include "tracer/lane_kernels.h"

namespace rayfarm::simd {
namespace {

// A sphere's centre and squared radius, W lanes of each.
template <class P>
struct SpherePack {
  typename P::D cx, cy, cz, r2;
};

// Where sphere_lanes_of() takes the spheres from: lanes [first, first + W).
template <class P>
struct OneSphere {  // one sphere in every lane, set once
  SpherePack<P> pack;
  const SpherePack<P>& at(int) const { return pack; }
};
template <class P>
struct SpherePerLane {  // each lane its own sphere
  const SphereLaneShapes& s;
  SpherePack<P> at(int f) const {
    const typename P::D radius = P::load(s.radius + f);
    return {P::load(s.center[0] + f), P::load(s.center[1] + f), P::load(s.center[2] + f), radius * radius};
  }
};

template <class P, class Spheres>
uint32_t sphere_lanes_of(const RayLanes& r, uint32_t active, const Spheres& spheres, double* t_out) {
  using D = typename P::D;
  constexpr int kW = P::kWidth;
  constexpr uint32_t kGroup = (1u << kW) - 1;
  const D zero = P::set1(0.0);
  uint32_t hits = 0;
  for (int first = 0; first < RayLanes::kLanes; first += kW) {
    const uint32_t lanes = (active >> first) & kGroup;
    if (!lanes) continue;
    const SpherePack<P>& s = spheres.at(first);
    const D cx = s.cx, cy = s.cy, cz = s.cz, r2 = s.r2;
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

template <class P>
uint32_t sphere_lanes(const RayLanes& r, uint32_t active, const double* center, double radius, double* t_out) {
  const OneSphere<P> one{{P::set1(center[0]), P::set1(center[1]), P::set1(center[2]), P::set1(radius * radius)}};
  return sphere_lanes_of<P>(r, active, one, t_out);
}

template <class P>
uint32_t sphere_lanes_per_lane(const RayLanes& r, uint32_t active, const SphereLaneShapes& spheres, double* t_out) {
  return sphere_lanes_of<P>(r, active, SpherePerLane<P>{spheres}, t_out);
}

}  // namespace
}  // namespace rayfarm::simd
