// The exact ray tests of shapes.h -- intersect_triangle(), intersect_sphere()
// and intersect_cone() -- for up to 16 rays of a packet at once, one SIMD lane
// per ray (the kernels are in tracer/simd/), and for shading the frames of
// up to 16 hits (hit_frame.h), their Phong terms (phong.h) and child rays
// (child_rays.h). Embree hands
// a user-geometry callback one primitive and a packet's rays; one pixel's
// samples, or their shadow rays towards one light, usually all reach the
// same primitive. A fill kernel sets a packet's rays up for them (float
// rounding, the watertight test's axes and shear) the same way.
//
// Every lane runs the scalar test's operations in the scalar test's order.
// IEEE double addition, subtraction, multiplication, division, square root
// and comparison are correctly rounded alike in SSE2, AVX2 and AVX-512, and
// the build fuses no multiply-add (-ffp-contract=off), so a lane's results
// have the bits the scalar test gives, on any CPU. The kernel width is picked
// once per scene from the CPU and capped like Embree's kernels
// (EmbreeOptions::max_isa), so tests run every width on one machine.
#pragma once

#include <cstdint>
#include <initializer_list>
#include <string>

namespace rayfarm {

// Embree's FLT_LARGE: a ray component beyond it in magnitude, or NaN, trips
// Embree's ray.valid() (an assertion in Debian's build, so a process abort).
constexpr double kMaxRayComponent = 1.844e18;

// A packet's rays, one entry per lane: the float-rounded rays Embree holds,
// in double, as ShearedRay (shapes.h) holds them. Plain data: the kernels'
// translation units are compiled for other ISAs, and must not instantiate
// the tracer's inline code. Filled by the fill kernel (LaneKernels::fill),
// as set_ray_lane() (ray_lane_fill.h) states it lane by lane.
struct RayLanes {
  static constexpr int kLanes = 16;
  alignas(64) double org[3][kLanes];  // x, y, z
  alignas(64) double dir[3][kLanes];
  alignas(64) double tfar[kLanes];    // t in (0, tfar)
  // The watertight triangle test's shear, each lane's for its own axes.
  alignas(64) double sx[kLanes], sy[kLanes], sz[kLanes];
  // Each lane's axis permutation (kx, ky, kz), one bit per lane: its kz is 0
  // (z_is_x), 1 (z_is_y) or 2 (neither); kx and ky follow cyclically,
  // swapped where `flipped` (its direction along kz is negative), as
  // ShearedRay picks them.
  uint32_t z_is_x = 0, z_is_y = 0, flipped = 0;
};

// The functions below are static, so each unit keeps its own copy: the
// kernels' units, compiled for other ISAs, must share no inline code with the
// tracer's.

// (kx, ky) for kz, as ShearedRay picks them.
static inline void axes_around(int kz, bool flipped, int& kx, int& ky) {
  kx = kz == 2 ? 0 : kz + 1;
  ky = kx == 2 ? 0 : kx + 1;
  if (flipped) {
    const int swap = kx;
    kx = ky, ky = swap;
  }
}

// Lane i's (kx, ky, kz) from its bits in `r`.
static inline void lane_axes(const RayLanes& r, int i, int& kx, int& ky, int& kz) {
  kz = (r.z_is_x >> i) & 1 ? 0 : ((r.z_is_y >> i) & 1 ? 1 : 2);
  axes_around(kz, (r.flipped >> i) & 1, kx, ky);
}

// Lanes (as bits) whose rays share one axis permutation: what the triangle
// kernel runs on at once, its shear being per permutation.
struct AxisClass {
  uint32_t lanes;
  int kx, ky, kz;
};
constexpr int kAxisClasses = 6;  // 3 choices of kz, each flipped or not

// The classes the `active` lanes of `r` fall into, written to out[0, n);
// returns n. Every active lane is in exactly one.
static inline int axis_classes(const RayLanes& r, uint32_t active, AxisClass* out) {
  const uint32_t by_kz[3] = {r.z_is_x, r.z_is_y & ~r.z_is_x, ~(r.z_is_x | r.z_is_y)};
  int n = 0;
  for (int kz = 0; kz < 3; ++kz) {
    for (const bool flip : {false, true}) {
      const uint32_t lanes = active & by_kz[kz] & (flip ? r.flipped : ~r.flipped);
      if (!lanes) continue;
      AxisClass& c = out[n++];
      c.lanes = lanes;
      c.kz = kz;
      axes_around(kz, flip, c.kx, c.ky);
    }
  }
  return n;
}

// The same rays as Embree takes them: each component rounded to float.
struct FloatLanes {
  alignas(64) float org[3][RayLanes::kLanes];
  alignas(64) float dir[3][RayLanes::kLanes];
};

// Per lane, what intersect_triangle() computes: t, and the edge weights v, w
// and det, from which it takes u = v / det and v = w / det. For the lanes a
// kernel reports as hits.
struct TriangleLaneHits {
  alignas(64) double t[RayLanes::kLanes];
  alignas(64) double v[RayLanes::kLanes], w[RayLanes::kLanes], det[RayLanes::kLanes];
};

// A cone slice as the cone kernel takes it: ConeShape's fields (shapes.h)
// and the slice's [s_lo, s_hi), as plain data.
struct ConeLaneShape {
  double center[3], axis[3];
  double half_length, mid_radius, slope, bound2, rmax2;
  double s_lo, s_hi;
};

// Spheres and cone slices one per lane, for the kernels that test each
// lane's ray against its own primitive (the start caches of rays walked one
// by one, EmbreeScene::occluded_alone()): the fields of a sphere (centre,
// radius) and of ConeLaneShape, lane by lane.
struct SphereLaneShapes {
  alignas(64) double center[3][RayLanes::kLanes];
  alignas(64) double radius[RayLanes::kLanes];
};
// A sphere's interior as the interior kernel takes it (EmbreeScene's
// Interior): the sphere, the squared distance from its centre within which
// a ray's start and exit must lie, and up to kMaxCaps caps, each the points
// p with dot(p - centre, axis) >= level.
struct InteriorLaneShape {
  static constexpr int kMaxCaps = 6;
  double center[3];
  double radius, reach2;
  int caps = 0;
  double axis[kMaxCaps][3];
  double level[kMaxCaps];
};
struct ConeLaneShapes {
  alignas(64) double center[3][RayLanes::kLanes], axis[3][RayLanes::kLanes];
  alignas(64) double half_length[RayLanes::kLanes], mid_radius[RayLanes::kLanes], slope[RayLanes::kLanes];
  alignas(64) double bound2[RayLanes::kLanes], rmax2[RayLanes::kLanes];
  alignas(64) double s_lo[RayLanes::kLanes], s_hi[RayLanes::kLanes];
};

// Lane i of `lanes` set to the sphere at center[0..2] or to the slice `c`.
static inline void set_sphere_lane(SphereLaneShapes& lanes, int i, const double* center, double radius) {
  for (int k = 0; k < 3; ++k) lanes.center[k][i] = center[k];
  lanes.radius[i] = radius;
}
static inline void set_cone_lane(ConeLaneShapes& lanes, int i, const ConeLaneShape& c) {
  for (int k = 0; k < 3; ++k) lanes.center[k][i] = c.center[k], lanes.axis[k][i] = c.axis[k];
  lanes.half_length[i] = c.half_length;
  lanes.mid_radius[i] = c.mid_radius;
  lanes.slope[i] = c.slope;
  lanes.bound2[i] = c.bound2;
  lanes.rmax2[i] = c.rmax2;
  lanes.s_lo[i] = c.s_lo;
  lanes.s_hi[i] = c.s_hi;
}

// Per lane, what intersect_cone() gives: t and the unnormalised outward
// normal. For the lanes the cone kernel reports as hits.
struct ConeLaneHits {
  alignas(64) double t[RayLanes::kLanes];
  alignas(64) double normal[3][RayLanes::kLanes];
};

// Up to 16 hits for the hit-frame kernel: what hit_frame() (hit_frame.h)
// takes, and what it gives, one lane per hit.
struct HitLanes {
  static constexpr int kLanes = 16;
  // In: the ray, its hit's t and the geometric normal.
  alignas(64) double org[3][kLanes];
  alignas(64) double dir[3][kLanes];
  alignas(64) double t[kLanes];
  alignas(64) double ng[3][kLanes];
  // Out: HitFrame's fields; `entering` has lane i's flag as bit i.
  alignas(64) double p[3][kLanes];
  alignas(64) double d[3][kLanes];
  alignas(64) double nf[3][kLanes];
  alignas(64) double p_front[3][kLanes];
  alignas(64) double p_back[3][kLanes];
  uint32_t entering = 0;
};

// Up to 16 lit hits for the Phong kernel: what phong_terms() (phong.h)
// takes, and what it gives, one lane per hit.
struct PhongLanes {
  static constexpr int kLanes = 16;
  // In: the vector to the light, the unit shading normal, the unit ray
  // direction, and the material's Ks and Phong exponent.
  alignas(64) double to_light[3][kLanes];
  alignas(64) double ns[3][kLanes];
  alignas(64) double d[3][kLanes];
  alignas(64) double ks[kLanes], shine[kLanes];
  // Out: n.l, and the highlight where `highlit` has the lane's bit; where
  // `scalar` has it too, the highlight's power left the kernel's range
  // (see simd/pow_lanes.h) and phong_terms() must give it.
  alignas(64) double n_dot_l[kLanes], highlight[kLanes];
  uint32_t highlit = 0, scalar = 0;
};

// Up to 16 hits' child rays for the child-ray kernel: what child_rays()
// (child_rays.h) takes beside a hit's frame and shading normal, and what it
// gives, one lane per hit.
struct ChildLanes {
  static constexpr int kLanes = 16;
  alignas(64) double eta[kLanes];  // in: n_from / n_to
  alignas(64) double refract_org[3][kLanes], refract_dir[3][kLanes];
  alignas(64) double mirror_org[3][kLanes], mirror_dir[3][kLanes];
  uint32_t total_internal = 0;  // lane i's flag as bit i
};

struct LaneKernels {
  // All 16 lanes from rays 0..count-1 (count >= 1) at orgs[3i..3i+2] and
  // dirs[3i..3i+2], t in (0, tfar); lanes count..15 repeat ray 0. Each
  // component is rounded to float (into `floats`) and back to double (into
  // `lanes`), and the axes and shear are ShearedRay's of that ray, bit for
  // bit: what a packet's exact twins are, at SIMD width. False when a
  // component of a ray is NaN or beyond kMaxRayComponent in magnitude: the
  // lanes are then not for Embree.
  bool (*fill)(const double* orgs, const double* dirs, int count, double tfar, RayLanes& lanes,
               FloatLanes& floats);
  // Bit i set: lane i (of the class's lanes, which share its axes) meets
  // the triangle with vertices a, b, c (x, y, z each) at a t in
  // (0, lanes.tfar[i]), exactly when intersect_triangle() on that lane's ray
  // says so.
  uint32_t (*triangle)(const RayLanes& lanes, const AxisClass& axes, const double* a, const double* b,
                       const double* c, TriangleLaneHits& out);
  // Likewise for intersect_sphere(), on the `active` lanes, with centre
  // (x, y, z) and radius; t[i] is the t it returns.
  uint32_t (*sphere)(const RayLanes& lanes, uint32_t active, const double* center, double radius, double* t);
  // Likewise for intersect_cone() on the slice (tnear 0), with its hits.
  uint32_t (*cone)(const RayLanes& lanes, uint32_t active, const ConeLaneShape& cone, ConeLaneHits& out);
  // The sphere kernel on `shape`'s sphere (t as above), then of the lanes it
  // hits, those whose start and exit (o + t d) lie within its reach; and
  // beyond[k]: those of them whose start or exit lies in cap k (see
  // EmbreeScene::intersect_inside(); the caps and the reach are drawn with
  // room to spare, so these products need no exact rounding).
  uint32_t (*interior)(const RayLanes& lanes, uint32_t active, const InteriorLaneShape& shape, double* t,
                       uint32_t* beyond);
  // The sphere and cone kernels with each lane's own primitive: lane i's ray
  // against sphere or slice i of `spheres` or `cones`, bit for bit as above.
  uint32_t (*sphere_per_lane)(const RayLanes& lanes, uint32_t active, const SphereLaneShapes& spheres, double* t);
  uint32_t (*cone_per_lane)(const RayLanes& lanes, uint32_t active, const ConeLaneShapes& cones, ConeLaneHits& out);
  // hit_frame() of lanes 0..count-1 (count <= 16), bit for bit; the lanes
  // after them up to the next multiple of the width are computed too, from
  // whatever they hold.
  void (*hit_frames)(HitLanes& hits, int count);
  // phong_terms() of lanes 0..count-1 (count <= 16), bit for bit, but for
  // the lanes it flags `scalar`.
  void (*phong)(PhongLanes& lights, int count);
  // Bit i set: light_in_front() (phong.h) of lane i's point p and unit
  // shading normal ns (x, y, z rows each) and the light at light[0..2], bit
  // for bit, for lanes 0..count-1 (count <= 16); the lanes after them up to
  // the next multiple of the width are computed too, from whatever they hold,
  // and left out of the bits.
  uint32_t (*facing)(const double (*p)[HitLanes::kLanes], const double (*ns)[HitLanes::kLanes], const double* light,
                     int count);
  // child_rays() of lanes 0..count-1 (count <= 16) of `frames`, with shading
  // normals `ns` (x, y, z rows) and out.eta, bit for bit; without
  // `refraction` only the mirror rays (the refraction fields are left as
  // they were, total_internal 0).
  void (*child_rays)(const HitLanes& frames, const double (*ns)[HitLanes::kLanes], ChildLanes& out, int count,
                     bool refraction);
};

// The widest kernels this CPU runs, at most `max_isa` ("" = no cap, else one
// of kEmbreeIsas: "sse2", "sse4.2" and "avx" give the 2-wide SSE2 kernels,
// "avx2" the 4-wide ones, "avx512" the 8-wide ones).
LaneKernels lane_kernels(const std::string& max_isa);

}  // namespace rayfarm
