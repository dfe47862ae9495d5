// The interior lane kernel (tracer/lane_kernels.h) over a Pack of W doubles
// (pack_*.h): the sphere kernel, then, W lanes at a time, whether each hit
// lane's start and exit lie within the interior's reach and in which of its
// caps. Included only by the kernels_*.cpp units.
#pragma once

#include <cstdint>

#include "tracer/lane_kernels.h"
#include "tracer/simd/sphere_lanes.h"

namespace rayfarm::simd {
namespace {

template <class P>
uint32_t interior_lanes(const RayLanes& r, uint32_t active, const InteriorLaneShape& shape, double* t,
                        uint32_t* beyond) {
  using D = typename P::D;
  constexpr int kW = P::kWidth;
  constexpr uint32_t kGroup = (1u << kW) - 1;
  const uint32_t hits = sphere_lanes<P>(r, active, shape.center, shape.radius, t);
  for (int k = 0; k < shape.caps; ++k) beyond[k] = 0;
  const D cx = P::set1(shape.center[0]), cy = P::set1(shape.center[1]), cz = P::set1(shape.center[2]);
  const D reach2 = P::set1(shape.reach2);
  uint32_t sure = 0;
  for (int first = 0; first < RayLanes::kLanes; first += kW) {
    const uint32_t lanes = (hits >> first) & kGroup;
    if (!lanes) continue;
    const D tt = P::load(t + first);
    const D sx = P::load(r.org[0] + first) - cx, sy = P::load(r.org[1] + first) - cy,
            sz = P::load(r.org[2] + first) - cz;  // the start, from the centre
    const D ex = sx + tt * P::load(r.dir[0] + first), ey = sy + tt * P::load(r.dir[1] + first),
            ez = sz + tt * P::load(r.dir[2] + first);  // the exit
    const auto within = P::and_(P::ge(reach2, sx * sx + sy * sy + sz * sz), P::ge(reach2, ex * ex + ey * ey + ez * ez));
    const uint32_t ok = lanes & P::bits(within);
    if (!ok) continue;
    sure |= ok << first;
    for (int k = 0; k < shape.caps; ++k) {
      const D ax = P::set1(shape.axis[k][0]), ay = P::set1(shape.axis[k][1]), az = P::set1(shape.axis[k][2]);
      const D level = P::set1(shape.level[k]);
      const auto in_cap = P::or_(P::ge(sx * ax + sy * ay + sz * az, level), P::ge(ex * ax + ey * ay + ez * az, level));
      beyond[k] |= (ok & P::bits(in_cap)) << first;
    }
  }
  return sure;
}

}  // namespace
}  // namespace rayfarm::simd
