// EmbreeScene's primitive boxes (embree_scene.h): the boxes Embree's
// bounds callbacks widen and hand to its BVH build, and the hulls the
// screen footprint projects (screen_footprint.h), from one place.
#include <algorithm>
#include <array>
#include <cmath>

#include "tracer/embree_scene.h"

namespace rayfarm {

Box EmbreeScene::sphere_box(uint32_t prim) const {
  const LocalSphere& s = spheres_[prim];
  const Vec3 r{s.radius, s.radius, s.radius};
  return {s.center - r, s.center + r};
}

// The box around the slice's two end discs: a disc of radius r with unit
// normal a reaches r * sqrt(1 - a_i^2) along axis i (tight for tubes at any
// angle).
Box EmbreeScene::slice_box(uint32_t prim) const {
  const ConeSlice& slice = cone_slices_[prim];
  const ConeShape& c = slice.shape;
  const double s0 = std::max(slice.s_lo, -c.half_length), s1 = std::min(slice.s_hi, c.half_length);
  const Vec3 a = c.axis;
  const Vec3 reach{std::sqrt(std::fmax(0.0, 1 - a.x * a.x)), std::sqrt(std::fmax(0.0, 1 - a.y * a.y)),
                   std::sqrt(std::fmax(0.0, 1 - a.z * a.z))};
  const double pad = 1e-9 * c.max_radius();
  const Vec3 e0 = reach * std::fabs(c.mid_radius + c.slope * s0) + Vec3{pad, pad, pad};
  const Vec3 e1 = reach * std::fabs(c.mid_radius + c.slope * s1) + Vec3{pad, pad, pad};
  const Vec3 p0 = c.center + s0 * a, p1 = c.center + s1 * a;
  const Vec3 b0 = p0 - e0, b1 = p1 - e1, c0 = p0 + e0, c1 = p1 + e1;
  return {{std::min(b0.x, b1.x), std::min(b0.y, b1.y), std::min(b0.z, b1.z)},
          {std::max(c0.x, c1.x), std::max(c0.y, c1.y), std::max(c0.z, c1.z)}};
}

void EmbreeScene::for_each_hull(const std::function<bool(const Vec3* points, int count)>& visit) const {
  for (const LocalTriangle& t : triangles_) {
    const Vec3 corners[3] = {t.a, t.b, t.c};
    if (!visit(corners, 3)) return;
  }
  const Vec3 m{box_margin_, box_margin_, box_margin_};
  const auto box = [&](const Box& b) {
    const std::array<Vec3, 8> corners = box_corners({b.lo - m, b.hi + m});
    return visit(corners.data(), 8);
  };
  for (uint32_t prim = 0; prim < spheres_.size(); ++prim) {
    if (!box(sphere_box(prim))) return;
  }
  for (uint32_t prim = 0; prim < cone_slices_.size(); ++prim) {
    if (!box(slice_box(prim))) return;
  }
}

}  // namespace rayfarm
