// A packet's RayLanes (lane_kernels.h) lane by lane, from and back to
// ShearedRay: set_ray_lane() is the scalar statement of what the fill kernel
// computes at SIMD width (the tests hold the two together), lane_ray() gives
// a lane's ray back for the scalar tests. Apart from lane_kernels.h because
// the kernels' translation units, compiled for other ISAs, must not include
// the tracer's inline code.
#pragma once

#include "tracer/lane_kernels.h"
#include "tracer/shapes.h"

namespace rayfarm {

// Lane i of `lanes` from `ray`, t in (0, tfar).
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
  const uint32_t bit = 1u << i, clear = ~bit;
  lanes.z_is_x = (lanes.z_is_x & clear) | (ray.kz == 0 ? bit : 0);
  lanes.z_is_y = (lanes.z_is_y & clear) | (ray.kz == 1 ? bit : 0);
  lanes.flipped = (lanes.flipped & clear) | (ray.dir[ray.kz] < 0 ? bit : 0);
}

inline Vec3 lane_org(const RayLanes& lanes, int i) { return lane_vec(lanes.org, i); }
inline Vec3 lane_dir(const RayLanes& lanes, int i) { return lane_vec(lanes.dir, i); }
// intersect_sphere()'s normal (unnormalised) at lane i's hit at t on the
// sphere around `center`, as the sphere kernel's hits take it.
inline Vec3 lane_sphere_normal(const RayLanes& lanes, int i, const Vec3& center, double t) {
  return (lane_org(lanes, i) - center) + t * lane_dir(lanes, i);
}

// Lane i's ray as ShearedRay(org, dir) would make it from the lane's org and
// dir: the same axes and shear, copied rather than computed again.
inline ShearedRay lane_ray(const RayLanes& lanes, int i) {
  ShearedRay ray;
  ray.org = lane_org(lanes, i);
  ray.dir = lane_dir(lanes, i);
  lane_axes(lanes, i, ray.kx, ray.ky, ray.kz);
  ray.sx = lanes.sx[i];
  ray.sy = lanes.sy[i];
  ray.sz = lanes.sz[i];
  return ray;
}

}  // namespace rayfarm
