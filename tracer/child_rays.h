// The rays a hit spawns (whitted.h): its mirror ray, and on a transmitting
// surface its Snell refraction ray, unless that is total internal
// reflection. Each leaves from the frame's offset origin (hit_frame.h) on
// the side it goes to. child_rays() states it for one hit; shading runs
// the child-ray kernel (lane_kernels.h), which gives the same bits for up
// to 16 hits at once, through child_lane().
#pragma once

#include <cmath>

#include "tracer/lane_kernels.h"
#include "tracer/vec3.h"

namespace rayfarm {

struct ChildRays {
  Vec3 refract_org, refract_dir;  // meaningless where total_internal
  bool total_internal = false;
  Vec3 mirror_org, mirror_dir;
};

// The offset origin on the side of the surface `dir` goes to.
inline Vec3 origin_towards(const Vec3& dir, const Vec3& nf, const Vec3& p_front, const Vec3& p_back) {
  return dot(dir, nf) < 0 ? p_back : p_front;
}

// d: the arriving ray's unit direction; ns: the unit shading normal and nf
// the geometric one, both on the side d comes from; eta = n_from / n_to.
inline ChildRays child_rays(const Vec3& d, const Vec3& ns, const Vec3& nf, const Vec3& p_front, const Vec3& p_back,
                            double eta) {
  ChildRays c;
  const double cos_i = -dot(d, ns);
  const double k = 1 - eta * eta * (1 - cos_i * cos_i);
  c.total_internal = k < 0;
  c.refract_dir = d * eta + ns * (eta * cos_i - std::sqrt(k));
  c.refract_org = origin_towards(c.refract_dir, nf, p_front, p_back);
  c.mirror_dir = d - ns * (2 * dot(d, ns));
  c.mirror_org = origin_towards(c.mirror_dir, nf, p_front, p_back);
  return c;
}

// Lane i of the kernel's output, as child_rays() returns it.
inline ChildRays child_lane(const ChildLanes& lanes, int i) {
  ChildRays c;
  c.refract_org = lane_vec(lanes.refract_org, i);
  c.refract_dir = lane_vec(lanes.refract_dir, i);
  c.total_internal = (lanes.total_internal >> i) & 1;
  c.mirror_org = lane_vec(lanes.mirror_org, i);
  c.mirror_dir = lane_vec(lanes.mirror_dir, i);
  return c;
}

}  // namespace rayfarm
