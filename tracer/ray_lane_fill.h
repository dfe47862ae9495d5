// Filling a packet's RayLanes (lane_kernels.h) from its exact rays: inline,
// since it runs for every lane of every packet. Apart from lane_kernels.h
// because the kernels' translation units, compiled for other ISAs, must not
// include the tracer's inline code.
#pragma once

#include "tracer/lane_kernels.h"
#include "tracer/shapes.h"

namespace rayfarm {

// Lane i of `lanes` from `ray`, t in (0, tfar). Fill the lanes in order from 0:
// lane 0 sets the packet's axes and the others clear shared_axes unless
// theirs are the same.
inline void set_ray_lane(RayLanes& lanes, int i, const ShearedRay& ray, double tfar) {
  lanes.org[0][i] = ray.org.x;
  lanes.org[1][i] = ray.org.y;
  lanes.org[2][i] = ray.org.z;
  lanes.dir[0][i] = ray.dir.x;
  lanes.dir[1][i] = ray.dir.y;
  lanes.dir[2][i] = ray.dir.z;
  lanes.sx[i] = ray.sx;
  lanes.sy[i] = ray.sy;
  lanes.sz[i] = ray.sz;
  lanes.tfar[i] = tfar;
  if (i == 0) {
    lanes.kx = ray.kx;
    lanes.ky = ray.ky;
    lanes.kz = ray.kz;
    lanes.shared_axes = true;
  } else {
    // kx and kz fix ky (the three are a permutation of 0, 1, 2). Comparing ky
    // too let GCC load kx and ky as one 8-byte word, just stored as two
    // 4-byte ones: a store-forwarding stall on every lane (8% of mount).
    lanes.shared_axes &= ray.kx == lanes.kx && ray.kz == lanes.kz;
  }
}

}  // namespace rayfarm
