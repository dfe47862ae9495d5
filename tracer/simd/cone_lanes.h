// The cone lane kernel (tracer/lane_kernels.h) over a Pack of W doubles
// (pack_*.h): intersect_cone() of tracer/shapes.h with tnear 0, operation
// for operation, on W rays at a time. Its early returns become lane masks,
// and both of its root paths (the quadratic's two roots, or the single root
// of a ray parallel to a generating line) are computed for every lane and
// the lane's own taken. One slice for every lane (cone_lanes()), or each
// lane its own (cone_lanes_per_lane()): the same operations on the same
// values either way. Included only by the kernels_*.cpp units.
#pragma once

#include <cstdint>

#include "tracer/lane_kernels.h"

namespace rayfarm::simd {
namespace {

// A slice's fields, W lanes of each.
template <class P>
struct ConePack {
  typename P::D cx, cy, cz, ax, ay, az, half_length, mid_radius, k, bound2, rmax2, s_lo, s_hi;
};

// Where cone_lanes_of() takes the slices from: lanes [first, first + W) of
// each field.
template <class P>
struct OneCone {  // one slice in every lane, set once
  ConePack<P> pack;
  explicit OneCone(const ConeLaneShape& c)
      : pack{P::set1(c.center[0]), P::set1(c.center[1]), P::set1(c.center[2]), P::set1(c.axis[0]),
             P::set1(c.axis[1]),   P::set1(c.axis[2]),   P::set1(c.half_length), P::set1(c.mid_radius),
             P::set1(c.slope),     P::set1(c.bound2),    P::set1(c.rmax2),     P::set1(c.s_lo),
             P::set1(c.s_hi)} {}
  const ConePack<P>& at(int) const { return pack; }
};
template <class P>
struct ConePerLane {  // each lane its own slice
  const ConeLaneShapes& c;
  ConePack<P> at(int f) const {
    return {P::load(c.center[0] + f), P::load(c.center[1] + f), P::load(c.center[2] + f),
            P::load(c.axis[0] + f),   P::load(c.axis[1] + f),   P::load(c.axis[2] + f),
            P::load(c.half_length + f), P::load(c.mid_radius + f), P::load(c.slope + f),
            P::load(c.bound2 + f),    P::load(c.rmax2 + f),     P::load(c.s_lo + f),
            P::load(c.s_hi + f)};
  }
};

template <class P, class Slices>
uint32_t cone_lanes_of(const RayLanes& r, uint32_t active, const Slices& slices, ConeLaneHits& out) {
  using D = typename P::D;
  constexpr int kW = P::kWidth;
  constexpr uint32_t kGroup = (1u << kW) - 1;
  const D zero = P::set1(0.0);
  uint32_t hits = 0;
  for (int first = 0; first < RayLanes::kLanes; first += kW) {
    if (!((active >> first) & kGroup)) continue;
    const ConePack<P>& c = slices.at(first);
    const D cx = c.cx, cy = c.cy, cz = c.cz, ax = c.ax, ay = c.ay, az = c.az;
    const D half_length = c.half_length, mid_radius = c.mid_radius, k = c.k, bound2 = c.bound2, rmax2 = c.rmax2;
    const D s_lo = c.s_lo, s_hi = c.s_hi;
    // intersect_cone()'s first test: a cone of no length is missed.
    const uint32_t lanes = (active >> first) & kGroup & P::bits(P::gt(half_length, zero));
    if (!lanes) continue;
    const D dx = P::load(r.dir[0] + first), dy = P::load(r.dir[1] + first), dz = P::load(r.dir[2] + first);
    const D dd = dx * dx + dy * dy + dz * dz;
    // The ray line passes no farther from the axis line than the larger radius.
    const D ocx = cx - P::load(r.org[0] + first), ocy = cy - P::load(r.org[1] + first),
            ocz = cz - P::load(r.org[2] + first);
    const D crx = dy * az - dz * ay, cry = dz * ax - dx * az, crz = dx * ay - dy * ax;  // d x axis
    const D m = ocx * crx + ocy * cry + ocz * crz;
    const D far_line = (rmax2 * (crx * crx + cry * cry + crz * crz)) * P::set1(1 + 1e-9);
    uint32_t live = lanes & P::bits(P::andnot(P::gt(m * m, far_line), P::gt(dd, zero)));
    if (!live) continue;  // about half of a cone's candidates: no division
    // The bounding sphere, from the origin moved to the point nearest the centre.
    const D inv_dd = P::set1(1.0) / dd;
    const D tc = (ocx * dx + ocy * dy + ocz * dz) * inv_dd;
    const D Ox = tc * dx - ocx, Oy = tc * dy - ocy, Oz = tc * dz - ocz;
    const D miss2 = bound2 - (Ox * Ox + Oy * Oy + Oz * Oz);
    const D h2 = miss2 * inv_dd;
    const D tfar = P::load(r.tfar + first);
    const D before = zero - tc, after = tc - tfar;
    const auto chord_before = P::and_(P::gt(zero, tc), P::ge(before * before, h2));
    const auto chord_after = P::and_(P::lt(tfar, tc), P::ge(after * after, h2));
    live &= ~P::bits(P::or_(P::lt(miss2, zero), P::or_(chord_before, chord_after)));
    if (!live) continue;
    // The side's quadratic A t^2 + 2B t + C = 0.
    const D so = Ox * ax + Oy * ay + Oz * az, sd = dx * ax + dy * ay + dz * az;
    const D opx = Ox - so * ax, opy = Oy - so * ay, opz = Oz - so * az;
    const D dpx = dx - sd * ax, dpy = dy - sd * ay, dpz = dz - sd * az;
    const D ro = mid_radius + k * so;
    const D A = (dpx * dpx + dpy * dpy + dpz * dpz) - k * k * sd * sd;
    const D B = (opx * dpx + opy * dpy + opz * dpz) - k * sd * ro;
    const D C = (opx * opx + opy * opy + opz * opz) - ro * ro;
    const auto linear = P::ge(P::set1(1e-12) * dd, P::copysign(A, zero));  // |A| <= 1e-12 dd
    // Parallel to a generating line: one root, unless B vanishes too.
    const auto linear_ok = P::and_(linear, P::gt(P::copysign(B, zero), P::set1(1e-300)));
    const D linear_root = P::neg(C) / (P::set1(2.0) * B);
    // Otherwise two, from the cancellation-free form.
    const D disc = B * B - A * C;
    const auto quadratic_ok = P::andnot(linear, P::ge(disc, zero));
    const D q = P::neg(B + P::copysign(P::sqrt(disc), B));
    const D q0 = q / A, q1 = P::select(P::ne(q, zero), C / q, q0);
    const auto swap = P::gt(q0, q1);
    const D root0 = P::select(linear, linear_root, P::select(swap, q1, q0));
    const D root1 = P::select(swap, q0, q1);
    live &= P::bits(P::or_(linear_ok, quadratic_ok));
    if (!live) continue;
    // The first root on the segment, on the slice and on the cone's own nappe.
    auto on_cone = [&](D t) {
      const D at = t + tc;
      const D s = so + t * sd;
      const auto off_slice = P::or_(P::gt(P::copysign(s, zero), half_length), P::or_(P::lt(s, s_lo), P::ge(s, s_hi)));
      const auto on_segment = P::and_(P::gt(at, zero), P::lt(at, tfar));
      const auto mirrored = P::lt(mid_radius + k * s, zero);
      return P::andnot(P::or_(off_slice, mirrored), on_segment);
    };
    const auto first_ok = on_cone(root0);
    const auto second_ok = P::andnot(P::or_(linear, first_ok), on_cone(root1));
    const uint32_t hit = live & P::bits(P::or_(first_ok, second_ok));
    if (!hit) continue;
    const D t = P::select(first_ok, root0, root1);
    P::store(out.t + first, t + tc);
    // The normal: the radial direction tilted by the slope.
    const D s = so + t * sd;
    const D kr = k * (mid_radius + k * s);
    P::store(out.normal[0] + first, ((Ox + t * dx) - s * ax) - kr * ax);
    P::store(out.normal[1] + first, ((Oy + t * dy) - s * ay) - kr * ay);
    P::store(out.normal[2] + first, ((Oz + t * dz) - s * az) - kr * az);
    hits |= hit << first;
  }
  return hits;
}

template <class P>
uint32_t cone_lanes(const RayLanes& r, uint32_t active, const ConeLaneShape& cone, ConeLaneHits& out) {
  return cone_lanes_of<P>(r, active, OneCone<P>(cone), out);
}

template <class P>
uint32_t cone_lanes_per_lane(const RayLanes& r, uint32_t active, const ConeLaneShapes& cones, ConeLaneHits& out) {
  return cone_lanes_of<P>(r, active, ConePerLane<P>{cones}, out);
}

}  // namespace
}  // namespace rayfarm::simd
