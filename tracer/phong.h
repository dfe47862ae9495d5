// The Phong terms of one light at a lit hit, SPD style (whitted.h): the
// diffuse factor n.l and the highlight Ks (r.v)^shine, r the light's
// direction mirrored about the shading normal. phong_terms() states them
// for one hit; shading runs them in lanes (LaneKernels::phong, same bits)
// through set_phong_lane() and phong_lane(). Before them, light_in_front()
// says which hits get a shadow ray at all.
#pragma once

#include <cmath>

#include "tracer/lane_kernels.h"
#include "tracer/portable_math.h"
#include "tracer/vec3.h"

namespace rayfarm {

struct PhongTerms {
  double n_dot_l = 0;
  double highlight = 0;  // read only where `highlit`
  bool highlit = false;  // Ks > 0 and the mirrored light faces the viewer
};

// `to_light` from the hit to the light, `ns` the unit shading normal, `d` the
// unit direction the ray arrived along.
inline PhongTerms phong_terms(const Vec3& to_light, const Vec3& ns, const Vec3& d, double ks, double shine) {
  PhongTerms terms;
  const double dist = std::sqrt(dot(to_light, to_light));
  terms.n_dot_l = dot(ns, to_light) / dist;
  if (ks > 0) {
    const Vec3 r = ns * (2 * terms.n_dot_l) - to_light / dist;
    const double r_dot_v = -dot(r, d);
    if (r_dot_v > 0) {
      terms.highlight = ks * portable_pow(r_dot_v, shine);
      terms.highlit = true;
    }
  }
  return terms;
}

// Whether the light is in front of the hit point p with unit shading normal
// ns, n . (light - p) > 0: the SPD rule for a shadow ray (none where the
// light is behind). Shading runs it in lanes (LaneKernels::facing, same bits).
inline bool light_in_front(const Vec3& p, const Vec3& ns, const Vec3& light) { return dot(ns, light - p) > 0; }

inline void set_phong_lane(PhongLanes& lanes, int i, const Vec3& to_light, const Vec3& ns, const Vec3& d,
                           double ks, double shine) {
  for (int c = 0; c < 3; ++c) {
    lanes.to_light[c][i] = to_light[c];
    lanes.ns[c][i] = ns[c];
    lanes.d[c][i] = d[c];
  }
  lanes.ks[i] = ks;
  lanes.shine[i] = shine;
}

// Lane i's terms after the kernel: phong_terms() of its inputs, bit for bit.
inline PhongTerms phong_lane(const PhongLanes& lanes, int i) {
  if ((lanes.scalar >> i) & 1) {
    return phong_terms(lane_vec(lanes.to_light, i), lane_vec(lanes.ns, i), lane_vec(lanes.d, i), lanes.ks[i],
                       lanes.shine[i]);
  }
  PhongTerms terms;
  terms.n_dot_l = lanes.n_dot_l[i];
  terms.highlit = (lanes.highlit >> i) & 1;
  if (terms.highlit) terms.highlight = lanes.highlight[i];
  return terms;
}

}  // namespace rayfarm
