// Ray intersection with every primitive rayfarm traces: spheres (`s`), open
// cones/cylinders without end caps (`c`) and the triangles polygons are cut
// into. Pure double-precision math with no Embree types, so it is unit-testable
// on its own and gives the same bits on every x86-64 CPU (IEEE double, no fused
// multiply-add: the build sets -ffp-contract=off); the Embree scene calls it
// from its user-geometry callbacks. The curved solvers move the ray origin next
// to the primitive before solving (as Embree's cone and Mitsuba's sphere code
// do) and avoid the cancellation-prone textbook quadratic (Ray Tracing Gems ch. 7).
#pragma once

#include <cmath>
#include <utility>

#include "tracer/vec3.h"

namespace rayfarm {

struct ShapeHit {
  double t = 0;
  Vec3 normal;  // outward, unnormalised (may be zero at a cone apex)
};

// Nearest t in (tnear, tfar) where o + t*d meets the sphere; d need not be unit.
// Ray Tracing Gems ch. 7: the discriminant is computed as a (r^2 - |l|^2), with l
// the offset of the centre from the ray's closest point, here via Lagrange's
// identity a |l|^2 = |f x d|^2; it loses no digits for small far spheres (unlike
// b^2 - ac), and a miss costs no division. The roots are c/q and q/a with
// q = b + sign(b) sqrt(disc), avoiding cancellation in either.
inline bool intersect_sphere(const Vec3& center, double radius, const Vec3& o, const Vec3& d,
                             double tnear, double tfar, ShapeHit& hit) {
  const Vec3 f = o - center;
  const double a = dot(d, d), r2 = radius * radius;
  const Vec3 fxd = cross(f, d);
  const double disc = r2 * a - dot(fxd, fxd);
  if (!(disc >= 0) || !(a > 0)) return false;
  const double b = -dot(f, d);
  const double c = dot(f, f) - r2;
  const double q = b + std::copysign(std::sqrt(disc), b);
  double t0 = q != 0 ? c / q : 0;
  double t1 = q / a;
  if (t0 > t1) std::swap(t0, t1);
  double t = t0;
  if (!(t > tnear && t < tfar)) {
    t = t1;
    if (!(t > tnear && t < tfar)) return false;
  }
  hit.t = t;
  hit.normal = f + t * d;
  return true;
}

// An NFF cone prepared for intersection, described from its midpoint: radius
// r(s) = mid_radius + slope * s at signed distance s in [-half_length,
// half_length] from `center` along the unit `axis` (s = -half_length is the base).
struct ConeShape {
  Vec3 center;
  Vec3 axis;
  double half_length = 0;
  double mid_radius = 0;
  double slope = 0;
  double bound2 = 0;  // squared radius of a sphere around the whole cone
  double rmax2 = 0;   // squared larger end radius (an infinite cylinder around the cone)

  static ConeShape make(const Vec3& base, double base_radius, const Vec3& apex, double apex_radius) {
    ConeShape c;
    const Vec3 axis = apex - base;
    const double len = rayfarm::length(axis);
    const double r0 = std::fabs(base_radius), r1 = std::fabs(apex_radius);
    c.axis = len > 0 ? axis / len : Vec3{0, 0, 1};
    c.center = base + 0.5 * axis;
    c.half_length = 0.5 * len;
    c.mid_radius = 0.5 * (r0 + r1);
    c.slope = len > 0 ? (r1 - r0) / len : 0;
    const double rmax = std::fmax(r0, r1);
    c.bound2 = c.half_length * c.half_length + rmax * rmax;
    c.rmax2 = rmax * rmax;
    return c;
  }
  Vec3 base() const { return center - half_length * axis; }
  Vec3 apex() const { return center + half_length * axis; }
  double max_radius() const { return mid_radius + std::fabs(slope) * half_length; }
};

// Nearest t in (tnear, tfar) where o + t*d meets the open cone's side.
// The origin is first moved along the ray to the point closest to the cone's
// centre (Embree's cone intersector does the same), so the coefficients stay
// small and precise for rays from far away; that point also gives a cheap
// bounding-sphere rejection. With O the moved origin relative to the centre,
// O' = O - (O.a)a, d' = d - (d.a)a and s(t) = O.a + t d.a, the side
// |O' + t d'|^2 = r(s(t))^2 is the quadratic A t^2 + 2B t + C = 0 below.
// Optionally only the slice s in [s_lo, s_hi) counts: a long cone can be split
// into slices with tighter bounding boxes, and since every slice runs the same
// arithmetic for the same ray, neighbouring slices neither overlap nor leave gaps.
inline bool intersect_cone(const ConeShape& cone, const Vec3& o, const Vec3& d, double tnear, double tfar,
                           ShapeHit& hit, double s_lo = -HUGE_VAL, double s_hi = HUGE_VAL) {
  const double dd = dot(d, d);
  if (!(dd > 0) || !(cone.half_length > 0)) return false;
  // Cheapest rejection first: the ray line passes farther from the axis line
  // than the larger radius (|oc . (d x a)| / |d x a|), no division needed.
  const Vec3 oc = cone.center - o;
  const Vec3 cr = cross(d, cone.axis);
  const double m = dot(oc, cr);
  if (m * m > cone.rmax2 * dot(cr, cr) * (1 + 1e-9)) return false;
  const double inv_dd = 1 / dd;
  const double tc = dot(oc, d) * inv_dd;
  const Vec3 O = tc * d - oc;  // the re-centred origin, relative to the centre
  const double miss2 = cone.bound2 - dot(O, O);
  if (miss2 < 0) return false;
  // The bounding sphere's chord [tc - h, tc + h] must overlap (tnear, tfar);
  // compared squared, h^2 = miss2 / dd, to save a square root.
  const double h2 = miss2 * inv_dd;
  if (tnear > tc && (tnear - tc) * (tnear - tc) >= h2) return false;
  if (tfar < tc && (tc - tfar) * (tc - tfar) >= h2) return false;
  const double so = dot(O, cone.axis), sd = dot(d, cone.axis);
  const Vec3 op = O - so * cone.axis, dp = d - sd * cone.axis;
  const double k = cone.slope, ro = cone.mid_radius + k * so;
  const double A = dot(dp, dp) - k * k * sd * sd;
  const double B = dot(op, dp) - k * sd * ro;
  const double C = dot(op, op) - ro * ro;
  double roots[2];
  int n = 0;
  if (std::fabs(A) <= 1e-12 * dd) {
    // A ray parallel to a generating line (for a cylinder: to the axis) meets the
    // surface at most once; for a cylinder B is 0 too and an open side is missed.
    if (std::fabs(B) <= 1e-300) return false;
    roots[n++] = -C / (2 * B);
  } else {
    const double disc = B * B - A * C;
    if (disc < 0) return false;
    const double q = -(B + std::copysign(std::sqrt(disc), B));
    double t0 = q / A, t1 = q != 0 ? C / q : t0;
    if (t0 > t1) std::swap(t0, t1);
    roots[n++] = t0;
    roots[n++] = t1;
  }
  for (int i = 0; i < n; ++i) {
    const double t = roots[i];
    if (!(t + tc > tnear && t + tc < tfar)) continue;
    const double s = so + t * sd;
    if (std::fabs(s) > cone.half_length || s < s_lo || s >= s_hi) continue;
    const double r = cone.mid_radius + k * s;
    if (r < 0) continue;  // the mirrored nappe of the double cone
    // Gradient of |Q'|^2 - r(s)^2: the radial direction tilted by the slope.
    const Vec3 radial = (O + t * d) - s * cone.axis;
    hit.t = t + tc;
    hit.normal = radial - (k * r) * cone.axis;
    return true;
  }
  return false;
}

// A ray prepared for watertight triangle tests (Woop, Benthin and Wald,
// "Watertight Ray/Triangle Intersection", JCGT 2013): the axis where the
// direction is largest becomes z, and a shear maps the direction onto +z, so
// every test reduces to 2D edge functions of the sheared vertices.
struct ShearedRay {
  Vec3 org, dir;
  int kx = 0, ky = 1, kz = 2;
  double sx = 0, sy = 0, sz = 1;

  ShearedRay() = default;
  ShearedRay(const Vec3& o, const Vec3& d) : org(o), dir(d) {
    const double ax = std::fabs(d.x), ay = std::fabs(d.y), az = std::fabs(d.z);
    kz = ax > ay ? (ax > az ? 0 : 2) : (ay > az ? 1 : 2);
    kx = kz == 2 ? 0 : kz + 1;
    ky = kx == 2 ? 0 : kx + 1;
    if (d[kz] < 0) std::swap(kx, ky);  // keeps the winding, so det's sign says the side
    sz = 1 / d[kz];
    sx = d[kx] * sz;
    sy = d[ky] * sz;
  }
};

struct TriangleHit {
  double t = 0;
  double u = 0, v = 0;  // hit = (1-u-v) a + u b + v c
};

// t in (tnear, tfar) where the ray meets triangle (a, b, c), either side. The
// edge function of an edge is the same products subtracted in the opposite
// order by the triangle on its other side, so it is exactly negated there: a
// ray through a shared edge or vertex hits at least one of the triangles
// (no cracks), whatever the vertex order. A ray in the triangle's plane misses.
inline bool intersect_triangle(const ShearedRay& r, const Vec3& a, const Vec3& b, const Vec3& c, double tnear,
                               double tfar, TriangleHit& hit) {
  const Vec3 A = a - r.org, B = b - r.org, C = c - r.org;
  const double ax = A[r.kx] - r.sx * A[r.kz], ay = A[r.ky] - r.sy * A[r.kz];
  const double bx = B[r.kx] - r.sx * B[r.kz], by = B[r.ky] - r.sy * B[r.kz];
  const double cx = C[r.kx] - r.sx * C[r.kz], cy = C[r.ky] - r.sy * C[r.kz];
  const double u = cx * by - cy * bx;  // weight of a
  const double v = ax * cy - ay * cx;  // weight of b
  const double w = bx * ay - by * ax;  // weight of c
  if ((u < 0 || v < 0 || w < 0) && (u > 0 || v > 0 || w > 0)) return false;
  const double det = u + v + w;
  if (det == 0) return false;
  const double tz = u * (r.sz * A[r.kz]) + v * (r.sz * B[r.kz]) + w * (r.sz * C[r.kz]);
  const double t = tz / det;
  if (!(t > tnear && t < tfar)) return false;
  hit.t = t;
  hit.u = v / det;
  hit.v = w / det;
  return true;
}

}  // namespace rayfarm
