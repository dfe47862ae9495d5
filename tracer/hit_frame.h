// The geometry of a hit, before any material: the ray's unit direction, the
// unit normal on the side the ray came from, the hit point and the origins
// new rays leave it from on either side. What shading starts from for every
// hit (whitted.cpp); the hit-frame kernel (LaneKernels::hit_frames) computes
// the same, 16 hits at a time, and is held to these bits.
#pragma once

#include <cmath>

#include "tracer/lane_kernels.h"
#include "tracer/ray_offset.h"
#include "tracer/vec3.h"

namespace rayfarm {

// Unit vector, or `fallback` when `v` has no usable length (degenerate normals
// must not turn into NaN pixels).
inline Vec3 unit_or(const Vec3& v, const Vec3& fallback) {
  const double len2 = dot(v, v);
  return len2 > 0 && std::isfinite(len2) ? v / std::sqrt(len2) : fallback;
}

struct HitFrame {
  Vec3 p;        // hit point, camera-relative
  Vec3 d;        // unit direction of the arriving ray
  Vec3 nf;       // unit geometric normal on the arriving ray's side
  Vec3 p_front;  // ray origin just off the surface on that side (RTG ch. 6)
  Vec3 p_back;   // and on the other side (refraction, and `pp` mirror rays that dip under)
  bool entering;  // arrived against the geometric normal (outside -> inside)
};

// The frame of the hit at `t` along the ray (org, dir) on a surface with
// geometric normal `ng` (any length; a zero one faces the ray).
inline HitFrame hit_frame(const Vec3& org, const Vec3& dir, double t, const Vec3& ng) {
  HitFrame f;
  f.d = unit_or(dir, Vec3{0, 0, 1});
  const Vec3 n = unit_or(ng, -f.d);
  // Which side the ray came from: for transmitters this is outside (entering)
  // versus inside; opaque surfaces are shaded on the side facing the ray.
  f.entering = dot(f.d, n) < 0;
  f.nf = f.entering ? n : -n;
  f.p = org + t * dir;
  // Offsets relative to the magnitude of the hit and of the ray's origin.
  const double scale = offset_scale(f.p, org);
  f.p_front = offset_ray_origin(f.p, f.nf, scale);
  f.p_back = offset_ray_origin(f.p, -f.nf, scale);
  return f;
}

// Lane i of the hit-frame kernel's input (LaneKernels::hit_frames), as
// hit_frame() takes it.
inline void set_hit_lane(HitLanes& h, int i, const Vec3& org, const Vec3& dir, double t, const Vec3& ng) {
  h.org[0][i] = org.x, h.org[1][i] = org.y, h.org[2][i] = org.z;
  h.dir[0][i] = dir.x, h.dir[1][i] = dir.y, h.dir[2][i] = dir.z;
  h.t[i] = t;
  h.ng[0][i] = ng.x, h.ng[1][i] = ng.y, h.ng[2][i] = ng.z;
}

// Lane i of the kernel's output, as hit_frame() returns it.
inline HitFrame hit_lane(const HitLanes& h, int i) {
  HitFrame f;
  f.p = lane_vec(h.p, i);
  f.d = lane_vec(h.d, i);
  f.nf = lane_vec(h.nf, i);
  f.p_front = lane_vec(h.p_front, i);
  f.p_back = lane_vec(h.p_back, i);
  f.entering = (h.entering >> i) & 1;
  return f;
}

}  // namespace rayfarm
