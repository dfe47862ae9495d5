// EmbreeScene: device, geometry upload, user-geometry callbacks for the
// analytic spheres and cones, and the eye-ray packet path.
#include "tracer/embree_scene.h"

#include <algorithm>
#include <atomic>
#include <cassert>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <stdexcept>

#include "tracer/embree_lanes.h"
#include "tracer/error.h"
#include "tracer/lane_kernels.h"
#include "tracer/ray_lane_fill.h"
#include "tracer/triangle_pieces.h"
#include "tracer/triangulate.h"

namespace rayfarm {

static_assert(DepartingLanes::kKinds == EmbreeScene::kKinds && DepartingLanes::kLanes == RayLanes::kLanes);
static_assert(Departure::kNone == RTC_INVALID_GEOMETRY_ID);

namespace {

uint64_t next_serial() {
  static std::atomic<uint64_t> last{0};
  return ++last;
}

void on_device_error(void* user, RTCError code, const char* message) {
  auto* error = static_cast<std::string*>(user);
  if (error->empty()) error->assign("Embree error " + std::to_string(int(code)) + ": " + (message ? message : ""));
}

// Float bounds that surely contain the double-precision box [lo, hi] widened
// by `margin` on every side.
RTCBounds widened_bounds(const Vec3& lo, const Vec3& hi, double margin) {
  auto down = [](double x) { return std::nextafter(static_cast<float>(x), -__builtin_huge_valf()); };
  auto up = [](double x) { return std::nextafter(static_cast<float>(x), __builtin_huge_valf()); };
  RTCBounds b;
  b.lower_x = down(lo.x - margin);
  b.lower_y = down(lo.y - margin);
  b.lower_z = down(lo.z - margin);
  b.upper_x = up(hi.x + margin);
  b.upper_y = up(hi.y + margin);
  b.upper_z = up(hi.z + margin);
  b.align0 = b.align1 = 0;
  return b;
}

// x rounded to float, through an empty asm statement the optimiser cannot
// see through. GCC 12's SLP vectorizer, pairing such round trips of
// neighbouring values into packed conversions, drops some of them: it left
// the z components of a packet's exact rays unrounded at -O2 and -O3, so a
// ray hit in the last bits differently in a packet than alone, and release
// builds rendered other pixels than -O1 builds. (Clang does not.)
float to_float(double x) {
  float f = static_cast<float>(x);
  asm("" : "+x"(f));
  return f;
}

// The smallest float >= t, for t >= 0: Embree's ray.tfar, which must never
// cull a primitive that meets the ray at t or nearer. The float above f >= 0
// is the next bit pattern (from +0 the smallest denormal); taken without a
// branch, since whether rounding went down is a coin toss, and without
// std::nextafter, a libm call.
float float_at_least(double t) {
  assert(!(t < 0));
  const float f = to_float(t);
  uint32_t bits;
  std::memcpy(&bits, &f, sizeof bits);
  bits += f < t;
  float up;
  std::memcpy(&up, &bits, sizeof up);
  return up;
}

// A ray as Embree holds it: each component rounded to float once, here.
// Embree walks these floats and every exact test runs on the same values in
// double (exact()), so the two never see different rays.
struct FloatRay {
  float org[3], dir[3];
  FloatRay(const Vec3& o, const Vec3& d) {
    EmbreeScene::check_ray(o, d);
    org[0] = to_float(o.x), org[1] = to_float(o.y), org[2] = to_float(o.z);
    dir[0] = to_float(d.x), dir[1] = to_float(d.y), dir[2] = to_float(d.z);
  }
  // Lane i of rays the fill kernel has rounded (and checked) already.
  FloatRay(const FloatLanes& lanes, int i) {
    for (int k = 0; k < 3; ++k) org[k] = lanes.org[k][i], dir[k] = lanes.dir[k][i];
  }
  ShearedRay exact() const { return ShearedRay(Vec3{org[0], org[1], org[2]}, Vec3{dir[0], dir[1], dir[2]}); }
};

// The fill kernel's lanes of rays 0..count-1 (LaneKernels::fill); a ray
// Embree cannot take throws, as check_ray() says.
void fill_checked(const LaneKernels& kernels, const Vec3* orgs, const Vec3* dirs, int count, double tfar,
                  RayLanes& soa, FloatLanes& floats) {
  static_assert(sizeof(Vec3) == 3 * sizeof(double), "the fill kernel reads Vec3 arrays as doubles");
  if (!kernels.fill(&orgs->x, &dirs->x, count, tfar, soa, floats)) {
    for (int i = 0; i < count; ++i) EmbreeScene::check_ray(orgs[i], dirs[i]);  // throws for the first bad ray
  }
}

}  // namespace

void check_embree_isa(const std::string& isa, const std::string& where) {
  if (isa.empty()) return;
  std::string names;
  for (const char* name : kEmbreeIsas) {
    if (isa == name) return;
    names += names.empty() ? name : std::string(", ") + name;
  }
  throw InputError(where + ": max_isa must be one of " + names + " (or empty: no cap), got \"" + isa + "\"");
}

// What every query hands its callbacks. Embree walks the BVH in an order that
// depends on the kernel width (BVH4 on SSE, BVH8 on AVX, different packet
// traversal), so nothing may depend on which primitive is met first:
// - every test runs in double on the float-rounded ray Embree holds (the same
//   bits on any CPU), for an intersection over the whole (0, inf), so its
//   answer does not depend on how near a hit was found before it;
// - the nearest hit is kept here, exactly, and a candidate replaces it when
//   (t, geom, prim) is lexicographically smaller: nearest first, ties (a ray
//   through a shared edge, coincident surfaces) to the lower kind (triangles,
//   spheres, cones) and then the lower primitive index, which follows the
//   scene file. Any total order would do; this one needs no extra data;
// - Embree's float tfar is only ever set to the float at or above that exact
//   t, and boxes are widened (box_margin()), so no primitive that could still
//   win, or tie, is culled, whatever rounding the kernel's box test has.
// Occlusion is the exact test on (0, tfar): whichever blocker is met first,
// the answer is the same. A ray's Departure is skipped by every test that
// could meet it: the scalar callbacks, the lane kernels' masks and the
// shadow caches.
struct EmbreeScene::Query {
  RTCIntersectContext context;  // first member: callbacks get its address
  struct Lane {
    ShearedRay ray;  // the float-rounded ray, in double (packets: see ray())
    double tfar;     // occlusion: end of the segment
    TraceHit best;   // intersection: nearest so far (geom invalid: none)
  };
  Lane* lanes;      // indexed like the rays of the Embree call
  Occluder found;   // occlusion: the primitive that blocked a single ray
  // A packet's lanes again, for the lane kernels (lane_kernels.h); null for
  // single rays.
  const RayLanes* packet = nullptr;
  // A packet's lanes whose Lane::ray is set: most rays of a packet only ever
  // meet the lane kernels, so ray() copies a lane's ray out of `packet` when
  // a scalar test first asks for it.
  uint32_t rays_set = 0;
  // What the rays depart, lane by lane.
  DepartingLanes departing;

  explicit Query(Lane* l) : lanes(l) { rtcInitIntersectContext(&context); }
  // A single ray's query: its lane 0.
  void set_lane(const ShearedRay& exact, double tfar, const Departure& departure) {
    Lane& lane = lanes[0];
    lane.ray = exact;
    lane.tfar = tfar;
    lane.best.geom = RTC_INVALID_GEOMETRY_ID;
    lane.best.t = HUGE_VAL;
    departing.set_single(departure);
  }
  const ShearedRay& ray(unsigned i) {
    if (packet && !((rays_set >> i) & 1)) {
      lanes[i].ray = lane_ray(*packet, int(i));
      rays_set |= 1u << i;
    }
    return lanes[i].ray;
  }
  // All 16 lanes of a packet, in `soa` for the lane kernels and as Embree
  // takes them, from rays 0..count-1, t in (0, tfar); the other lanes are
  // disabled (the kernels never report them: lanes_for() leaves them out)
  // and repeat ray 0, for Embree may still run callbacks on them.
  void fill_packet(const LaneKernels& kernels, RTCRay16& rays, int* valid, RayLanes& soa, const Vec3* orgs,
                   const Vec3* dirs, int count, double tfar, const Departure* departures);
  // Whether a hit at t on (geom, prim) is nearer than b by the tie rule.
  static bool closer(double t, uint32_t geom, uint32_t prim, const TraceHit& b) {
    if (t != b.t) return t < b.t;
    return geom != b.geom ? geom < b.geom : prim < b.prim;
  }
  static bool closer(const TraceHit& a, const TraceHit& b) { return closer(a.t, a.geom, a.prim, b); }
};

namespace {
// A sphere or cone hit as a TraceHit (no barycentrics); always true.
bool curved_hit(const ShapeHit& h, uint32_t prim, TraceHit& out) {
  out.t = h.t;
  out.ng = h.normal;
  out.u = out.v = 0;
  out.prim = prim;
  return true;
}
}  // namespace

bool EmbreeScene::hit_sphere(uint32_t prim, const ShearedRay& r, double tfar, TraceHit& out) const {
  const LocalSphere& s = spheres_[prim];
  ShapeHit h;
  return intersect_sphere(s.center, s.radius, r.org, r.dir, 0.0, tfar, h) && curved_hit(h, prim, out);
}

bool EmbreeScene::hit_cone(uint32_t prim, const ShearedRay& r, double tfar, TraceHit& out) const {
  const ConeSlice& slice = cone_slices_[prim];
  ShapeHit h;
  return intersect_cone(slice.shape, r.org, r.dir, 0.0, tfar, h, slice.s_lo, slice.s_hi) &&
         curved_hit(h, prim, out);
}

bool EmbreeScene::hit_triangle(uint32_t piece, const ShearedRay& r, double tfar, TraceHit& out) const {
  bool found = false;
  const TrianglePiece& p = pieces_[piece];
  for (uint32_t prim = p.first; prim < p.first + p.count; ++prim) {
    const LocalTriangle& tri = triangles_[prim];
    TriangleHit h;
    // The tie rule within the piece: the lower index, met first, keeps a tie.
    if (!intersect_triangle(r, tri.a, tri.b, tri.c, 0.0, tfar, h) || (found && !(h.t < out.t))) continue;
    out.t = h.t;
    out.ng = triangle_normals_[prim];
    out.u = h.u;
    out.v = h.v;
    out.prim = prim;
    found = true;
  }
  return found;
}

bool EmbreeScene::hit_primitive(uint32_t geom, uint32_t prim, const ShearedRay& r, double tfar,
                                TraceHit& out) const {
  switch (geom) {
    case kTriangles: return hit_triangle(prim, r, tfar, out);
    case kSpheres: return hit_sphere(prim, r, tfar, out);
    case kCones: return hit_cone(prim, r, tfar, out);
    default: return false;
  }
}

// User-geometry callbacks: C entry points over the hit_* tests.
struct EmbreeCallbacks {
  using Test = bool (EmbreeScene::*)(uint32_t, const ShearedRay&, double, TraceHit&) const;

  template <Test test>
  static void intersect(const RTCIntersectFunctionNArguments* args) {
    const auto* es = static_cast<const EmbreeScene*>(args->geometryUserPtr);
    auto* query = reinterpret_cast<EmbreeScene::Query*>(args->context);
    RTCRayN* rays = RTCRayHitN_RayN(args->rayhit, args->N);
    for (unsigned i = 0; i < args->N; ++i) {
      if (args->valid[i] != -1) continue;
      const unsigned id = RTCRayN_id(rays, args->N, i);
      if (may_depart(test) && query->departing.skips(id, args->geomID, args->primID)) continue;
      TraceHit hit;
      if (!(es->*test)(args->primID, query->ray(id), HUGE_VAL, hit)) continue;
      EmbreeScene::Query::Lane& lane = query->lanes[id];
      hit.geom = args->geomID;
      if (!EmbreeScene::Query::closer(hit, lane.best)) continue;
      lane.best = hit;
      RTCRayN_tfar(rays, args->N, i) = float_at_least(hit.t);
    }
  }
  template <Test test>
  static void occluded(const RTCOccludedFunctionNArguments* args) {
    const auto* es = static_cast<const EmbreeScene*>(args->geometryUserPtr);
    auto* query = reinterpret_cast<EmbreeScene::Query*>(args->context);
    for (unsigned i = 0; i < args->N; ++i) {
      if (args->valid[i] != -1) continue;
      const unsigned id = RTCRayN_id(args->ray, args->N, i);
      if (may_depart(test) && query->departing.skips(id, args->geomID, args->primID)) continue;
      TraceHit hit;
      if (!(es->*test)(args->primID, query->ray(id), query->lanes[id].tfar, hit)) continue;
      RTCRayN_tfar(args->ray, args->N, i) = -__builtin_huge_valf();
      query->found = {args->geomID, args->primID};
    }
  }

  // Triangles, spheres and cones in a packet run the lane kernels
  // (lane_kernels.h), which give the bits hit_triangle(), hit_sphere() and
  // hit_cone() would, ray by ray; lanes_for() says when the rays go one by
  // one instead, through `test`. Lanes that depart the primitive are not
  // tested.
  template <Test test>
  static void intersect_lanes(const RTCIntersectFunctionNArguments* args) {
    const auto* es = static_cast<const EmbreeScene*>(args->geometryUserPtr);
    auto* query = reinterpret_cast<EmbreeScene::Query*>(args->context);
    RTCRayN* rays = RTCRayHitN_RayN(args->rayhit, args->N);
    const LaneWindow window = lanes_for(*query, args->valid, rays, args->N, min_lanes(test));
    if (!window.active) return intersect<test>(args);
    const uint32_t active = window.active;
    const uint32_t tested = may_depart(test) ? active & ~query->departing.skipping(args->geomID, args->primID) : active;
    if (!tested) return;
    keep_nearer_hits(*es, *query, args->geomID, args->primID, tested, [&](int i, double t) {
      RTCRayN_tfar(rays, args->N, i - window.first) = float_at_least(t);
    });
  }
  // Likewise for occlusion: `blocked(es, packet, active)` gives the lanes
  // the primitive blocks.
  template <Test test, class Blocked>
  static void occluded_lanes(const RTCOccludedFunctionNArguments* args, Blocked&& blocked) {
    const auto* es = static_cast<const EmbreeScene*>(args->geometryUserPtr);
    auto* query = reinterpret_cast<EmbreeScene::Query*>(args->context);
    const LaneWindow window = lanes_for(*query, args->valid, args->ray, args->N, min_lanes(test));
    if (!window.active) return occluded<test>(args);
    const uint32_t active = window.active;
    const uint32_t tested = may_depart(test) ? active & ~query->departing.skipping(args->geomID, args->primID) : active;
    if (tested) block(args, window, blocked(*es, *query->packet, tested), query);
  }

  // The hits of primitive `prim` of kind `geom` on the `active` lanes of the
  // query's packet, from the lane kernels, each made its lane's nearest
  // where the tie rule says it is nearer (as intersect<>() does);
  // `kept(i, t)` hears of each one kept. What the callbacks run, and what
  // rays inside a sphere meet (intersect_inside()).
  template <class Kept>
  static void keep_nearer_hits(const EmbreeScene& es, EmbreeScene::Query& query, uint32_t geom, uint32_t prim,
                               uint32_t active, Kept&& kept) {
    const RayLanes& packet = *query.packet;
    if (geom == EmbreeScene::kTriangles) {
      const EmbreeScene::TrianglePiece& piece = es.pieces_[prim];
      AxisClass classes[kAxisClasses];
      const int n = axis_classes(packet, active, classes);
      for (uint32_t tri = piece.first; tri < piece.first + piece.count; ++tri) {
        for (int c = 0; c < n; ++c) {
          TriangleLaneHits lanes;
          for (uint32_t bits = triangle_lanes(es, packet, classes[c], es.triangles_[tri], lanes); bits;
               bits &= bits - 1) {
            const int i = __builtin_ctz(bits);
            keep_nearer(query, i, lanes.t[i], geom, tri, kept, [&](TraceHit& hit) {
              hit.u = lanes.v[i] / lanes.det[i];  // as intersect_triangle() takes them
              hit.v = lanes.w[i] / lanes.det[i];
              hit.ng = es.triangle_normals_[tri];
            });
          }
        }
      }
    } else if (geom == EmbreeScene::kSpheres) {
      const EmbreeScene::LocalSphere& s = es.spheres_[prim];
      alignas(64) double t[RayLanes::kLanes];
      for (uint32_t bits = sphere_lanes(es, packet, active, s, t); bits; bits &= bits - 1) {
        const int i = __builtin_ctz(bits);
        keep_nearer(query, i, t[i], geom, prim, kept,
                    [&](TraceHit& hit) { hit.ng = lane_sphere_normal(packet, i, s.center, hit.t); });
      }
    } else if (geom == EmbreeScene::kCones) {
      ConeLaneHits lanes;
      for (uint32_t bits = cone_lanes(es, packet, active, prim, lanes); bits; bits &= bits - 1) {
        const int i = __builtin_ctz(bits);
        keep_nearer(query, i, lanes.t[i], geom, prim, kept,
                    [&](TraceHit& hit) { hit.ng = lane_vec(lanes.normal, i); });
      }
    }
  }
  static void intersect_triangles(const RTCIntersectFunctionNArguments* args) {
    intersect_lanes<&EmbreeScene::hit_triangle>(args);
  }
  static void occluded_triangles(const RTCOccludedFunctionNArguments* args) {
    occluded_lanes<&EmbreeScene::hit_triangle>(args, [args](const EmbreeScene& es, const RayLanes& packet,
                                                            uint32_t active) {
      return piece_blocks(es, packet, active, es.pieces_[args->primID]);
    });
  }
  static void intersect_spheres(const RTCIntersectFunctionNArguments* args) {
    intersect_lanes<&EmbreeScene::hit_sphere>(args);
  }
  static void occluded_spheres(const RTCOccludedFunctionNArguments* args) {
    occluded_lanes<&EmbreeScene::hit_sphere>(args, [args](const EmbreeScene& es, const RayLanes& packet,
                                                          uint32_t active) {
      alignas(64) double t[RayLanes::kLanes];
      return sphere_lanes(es, packet, active, es.spheres_[args->primID], t);
    });
  }
  static void intersect_cones(const RTCIntersectFunctionNArguments* args) {
    intersect_lanes<&EmbreeScene::hit_cone>(args);
  }
  static void occluded_cones(const RTCOccludedFunctionNArguments* args) {
    occluded_lanes<&EmbreeScene::hit_cone>(args, [args](const EmbreeScene& es, const RayLanes& packet,
                                                        uint32_t active) {
      ConeLaneHits lanes;
      return cone_lanes(es, packet, active, args->primID, lanes);
    });
  }

  static uint32_t triangle_lanes(const EmbreeScene& es, const RayLanes& lanes, const AxisClass& axes,
                                 const EmbreeScene::LocalTriangle& tri, TriangleLaneHits& out) {
    const double a[3] = {tri.a.x, tri.a.y, tri.a.z}, b[3] = {tri.b.x, tri.b.y, tri.b.z};
    const double c[3] = {tri.c.x, tri.c.y, tri.c.z};
    return es.lane_kernels_.triangle(lanes, axes, a, b, c, out);
  }
  // The lanes of `active` whose rays meet a triangle of the piece in
  // (0, tfar): the kernel once per axis class and triangle, until every
  // lane is blocked.
  static uint32_t piece_blocks(const EmbreeScene& es, const RayLanes& lanes, uint32_t active,
                               const EmbreeScene::TrianglePiece& piece) {
    AxisClass classes[kAxisClasses];
    const int n = axis_classes(lanes, active, classes);
    uint32_t bits = 0;
    for (uint32_t prim = piece.first; prim < piece.first + piece.count && bits != active; ++prim) {
      for (int c = 0; c < n; ++c) {
        TriangleLaneHits hits;
        bits |= triangle_lanes(es, lanes, classes[c], es.triangles_[prim], hits);
      }
    }
    return bits;
  }
  static uint32_t sphere_lanes(const EmbreeScene& es, const RayLanes& lanes, uint32_t active,
                               const EmbreeScene::LocalSphere& s, double* t) {
    const double center[3] = {s.center.x, s.center.y, s.center.z};
    return es.lane_kernels_.sphere(lanes, active, center, s.radius, t);
  }
  static uint32_t cone_lanes(const EmbreeScene& es, const RayLanes& lanes, uint32_t active, uint32_t slice,
                             ConeLaneHits& out) {
    return es.lane_kernels_.cone(lanes, active, EmbreeScene::cone_lane_shape(es.cone_slices_[slice]), out);
  }
  // Makes the hit at t on (geom, prim) lane i's nearest if the tie rule says
  // it is nearer, as intersect<>() does; `complete` fills in the hit's other
  // fields only then, and `kept(i, t)` hears of it.
  template <class Kept, class Complete>
  static void keep_nearer(EmbreeScene::Query& query, int i, double t, uint32_t geom, uint32_t prim, Kept& kept,
                          Complete&& complete) {
    TraceHit& best = query.lanes[i].best;
    if (!EmbreeScene::Query::closer(t, geom, prim, best)) return;
    best.t = t;
    best.geom = geom;
    best.prim = prim;
    best.u = best.v = 0;  // a sphere's hit has none; a triangle's completes them
    complete(best);
    kept(i, t);
  }
  // Marks the lanes in `bits` occluded, as occluded<>() does.
  static void block(const RTCOccludedFunctionNArguments* args, const LaneWindow& window, uint32_t bits,
                    EmbreeScene::Query* query) {
    for (; bits; bits &= bits - 1) {
      RTCRayN_tfar(args->ray, args->N, __builtin_ctz(bits) - window.first) = -__builtin_huge_valf();
      query->found = {args->geomID, args->primID};
    }
  }
  // The fewest active lanes for which a kind's kernel beats its scalar test
  // run ray by ray: two for triangles (four made mount 1.01x slower), one
  // for spheres and cones, whose scalar tests branch unpredictably (against
  // two: rings 0.97x, 11 pairs; balls 0.99x, 15 pairs; mount 1.00x).
  static constexpr int min_lanes(Test test) { return test == &EmbreeScene::hit_triangle ? 2 : 1; }
  // Whether a ray may depart a primitive of the kind `test` tests (Departure).
  static constexpr bool may_depart(Test test) { return test != &EmbreeScene::hit_triangle; }
  // The lanes a kernel should run (embree_lanes.h): none for a single ray,
  // for Embree's lanes that are not the query's, or for fewer active lanes
  // than `min_active`.
  static LaneWindow lanes_for(const EmbreeScene::Query& query, const int* valid, RTCRayN* rays, unsigned n,
                              int min_active) {
    if (!query.packet) return {};
    const LaneWindow window =
        lane_window(valid, reinterpret_cast<const int*>(&RTCRayN_id(rays, n, 0)), n, RayLanes::kLanes);
    return __builtin_popcount(window.active) >= min_active ? window : LaneWindow{};
  }

  static void sphere_bounds(const RTCBoundsFunctionArguments* args) {
    const auto* es = static_cast<const EmbreeScene*>(args->geometryUserPtr);
    const Box box = es->sphere_box(args->primID);
    *args->bounds_o = widened_bounds(box.lo, box.hi, es->box_margin_);
  }

  static void cone_bounds(const RTCBoundsFunctionArguments* args) {
    const auto* es = static_cast<const EmbreeScene*>(args->geometryUserPtr);
    const Box box = es->slice_box(args->primID);
    *args->bounds_o = widened_bounds(box.lo, box.hi, es->box_margin_);
  }

  static void triangle_bounds(const RTCBoundsFunctionArguments* args) {
    const auto* es = static_cast<const EmbreeScene*>(args->geometryUserPtr);
    const Box& box = es->piece_boxes_[args->primID];
    *args->bounds_o = widened_bounds(box.lo, box.hi, es->box_margin_);
  }
};

namespace {

// How far every box handed to Embree is widened. Embree's float slab test of
// a box [lo, hi] computes (lo - org) / dir with a few roundings and, on some
// kernels, an approximate reciprocal: its error is below about 2^-20 (|lo| +
// |org|) / |dir_i| per axis. A ray meeting a primitive at p stays inside the
// box widened by m for a t-interval of m / |dir_i| around p on every axis, so
// m = 2^-16 R, with R bounding every coordinate of the geometry and of any ray
// origin (rays start at the camera, the local origin, or on the geometry),
// leaves a factor 16 to spare on every kernel. Boxes grow by a few parts in
// 10^5 of the scene's size, which costs no measurable time.
double box_margin(const Scene& scene, const Vec3& origin) {
  double r = 0;
  auto reach = [&](const Vec3& world, double radius) {
    const Vec3 p = world - origin;
    r = std::max({r, std::fabs(p.x) + radius, std::fabs(p.y) + radius, std::fabs(p.z) + radius});
  };
  for (const Sphere& s : scene.spheres) reach(s.center, std::fabs(s.radius));
  for (const Cone& c : scene.cones) {
    reach(c.base, std::fabs(c.base_radius));
    reach(c.apex, std::fabs(c.apex_radius));
  }
  for (const Vec3& v : scene.vertices) reach(v, 0);
  return std::ldexp(r, -16);
}

// The box around points[0, count), as its squared diagonal.
double box_width2(const Vec3* points, int count) {
  Vec3 lo = points[0], hi = points[0];
  for (int i = 1; i < count; ++i) {
    const Vec3& p = points[i];
    lo = {std::min(lo.x, p.x), std::min(lo.y, p.y), std::min(lo.z, p.z)};
    hi = {std::max(hi.x, p.x), std::max(hi.y, p.y), std::max(hi.z, p.z)};
  }
  const Vec3 size = hi - lo;
  return dot(size, size);
}

// How wide, as a share of the scene's diagonal, the origins of a packet of
// mirror or refraction rays may spread before its rays go one by one through
// Embree's single-ray walk and the scalar tests. Embree's 16-wide call walks
// user geometry for the packet as a whole (its "Chunk" intersector: every
// node tested for all active rays, a leaf handed the rays through its box),
// whatever the context flags say; rays that start far apart share few nodes
// and pay for all of them. Rings' deep mirror rays bounce from tube to tube: at
// 0.14 it rendered in 0.91x the time (7 interleaved runs; 0.10 and 0.20
// alike); the refraction rays through mount's glass spheres start side by
// side and stay in packets (0.99x), and so do balls', gears' and tetra's.
// Every packet from the third level on one by one made mount 2.3x slower.
constexpr double kScatteredShare = 0.14;

double scattered_width2(RTCScene scene) {
  RTCBounds b;
  rtcGetSceneBounds(scene, &b);
  const Vec3 size{double(b.upper_x) - b.lower_x, double(b.upper_y) - b.lower_y, double(b.upper_z) - b.lower_z};
  const double width2 = kScatteredShare * kScatteredShare * dot(size, size);
  return std::isfinite(width2) ? width2 : HUGE_VAL;  // an empty scene's box is inverted infinities
}

}  // namespace

EmbreeScene::EmbreeScene(const Scene& scene, const EmbreeOptions& options)
    : origin_(scene.camera.from),
      serial_(next_serial()),
      box_margin_(box_margin(scene, scene.camera.from)),
      lane_kernels_(lane_kernels(options.max_isa)) {
  const auto start = std::chrono::steady_clock::now();
  check_embree_isa(options.max_isa, "Embree options");
  const std::string config = options.max_isa.empty() ? "" : "max_isa=" + options.max_isa;
  device_ = rtcNewDevice(config.empty() ? nullptr : config.c_str());
  if (!device_) throw std::runtime_error("Embree: cannot create device (error " +
                                         std::to_string(int(rtcGetDeviceError(nullptr))) + ")");
  rtcSetDeviceErrorFunction(device_, on_device_error, &error_);
  scene_ = rtcNewScene(device_);
  rtcSetSceneFlags(scene_, options.robust_bvh ? RTC_SCENE_FLAG_ROBUST : RTC_SCENE_FLAG_NONE);
  quality_ = options.high_quality ? RTC_BUILD_QUALITY_HIGH : RTC_BUILD_QUALITY_MEDIUM;
  rtcSetSceneBuildQuality(scene_, quality_);
  add_triangles(scene);
  add_spheres(scene);
  add_cones(scene);
  rtcCommitScene(scene_);
  check_error("building the scene");
  scattered_width2_ = scattered_width2(scene_);
  find_interiors(scene);
  check_error("finding what reaches into the spheres");
  std::vector<Box>().swap(piece_boxes_);  // only the build asks for bounds
  build_seconds_ = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

void EmbreeScene::bounds(Vec3& lo, Vec3& hi) const {
  RTCBounds b;
  rtcGetSceneBounds(scene_, &b);
  lo = {b.lower_x, b.lower_y, b.lower_z};
  hi = {b.upper_x, b.upper_y, b.upper_z};
}

EmbreeScene::~EmbreeScene() {
  if (scene_) rtcReleaseScene(scene_);
  if (device_) rtcReleaseDevice(device_);
}

void EmbreeScene::throw_invalid_ray(const Vec3& org, const Vec3& dir) {
  char buf[256];
  std::snprintf(buf, sizeof buf,
                "the scene's numbers make a ray the tracer cannot take (origin %g %g %g, direction %g %g %g): "
                "geometry too large or degenerate",
                org.x, org.y, org.z, dir.x, dir.y, dir.z);
  throw InputError(buf);
}

void EmbreeScene::check_error(const char* what) const {
  if (!error_.empty()) throw std::runtime_error(error_ + " (" + what + ")");
}

namespace {
uint32_t material_of(const Scene& scene, uint32_t index) {
  return index < scene.materials.size() ? index : 0;
}
}  // namespace

void EmbreeScene::add_user_geometry(uint32_t id, size_t count, RTCBoundsFunction bounds,
                                    RTCIntersectFunctionN intersect, RTCOccludedFunctionN occluded) {
  RTCGeometry geometry = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_USER);
  rtcSetGeometryUserPrimitiveCount(geometry, static_cast<unsigned>(count));
  rtcSetGeometryUserData(geometry, this);
  rtcSetGeometryBoundsFunction(geometry, bounds, nullptr);
  rtcSetGeometryIntersectFunction(geometry, intersect);
  rtcSetGeometryOccludedFunction(geometry, occluded);
  rtcSetGeometryBuildQuality(geometry, quality_);
  rtcCommitGeometry(geometry);
  rtcAttachGeometryByID(scene_, geometry, id);
  rtcReleaseGeometry(geometry);
  check_error(id == kTriangles ? "triangles" : id == kSpheres ? "spheres" : "cones");
}

void EmbreeScene::add_triangles(const Scene& scene) {
  if (scene.polygons.empty()) return;
  const bool any_smooth = !scene.normals.empty();
  // Every array is sized before it is filled: grown by doubling, gears' 36,610
  // triangles and 21,273 pieces cost thousands of page faults and copies.
  size_t most_triangles = 0;
  for (const Polygon& poly : scene.polygons) most_triangles += poly.count >= 3 ? poly.count - 2 : 0;
  triangles_.reserve(most_triangles);
  triangle_normals_.reserve(most_triangles);
  indices_.reserve(3 * most_triangles);
  materials_[kTriangles].reserve(most_triangles);
  if (any_smooth) smooth_.reserve(most_triangles);
  for (const Polygon& poly : scene.polygons) {
    if (poly.count < 3 || size_t(poly.first) + poly.count > scene.vertices.size()) continue;
    const Vec3* v = &scene.vertices[poly.first];
    const Vec3 facing = polygon_normal(v, poly.count);
    const std::vector<uint32_t> tris = triangulate_polygon(v, poly.count);
    for (size_t t = 0; t + 2 < tris.size(); t += 3) {
      uint32_t a = tris[t], b = tris[t + 1], c = tris[t + 2];
      // Every triangle faces like its polygon, so Ng tells inside from outside.
      if (dot(cross(v[b] - v[a], v[c] - v[a]), facing) < 0) std::swap(b, c);
      indices_.insert(indices_.end(), {poly.first + a, poly.first + b, poly.first + c});
      // Shared vertices become bit-identical local points, as the watertight
      // test needs (intersect_triangle()).
      const Vec3 la = to_local(v[a]), lb = to_local(v[b]), lc = to_local(v[c]);
      triangles_.push_back({la, lb, lc});
      triangle_normals_.push_back(cross(lb - la, lc - la));
      materials_[kTriangles].push_back(material_of(scene, poly.material));
      if (any_smooth) smooth_.push_back(poly.has_normals ? 1 : 0);
    }
  }
  if (any_smooth) normals_ = scene.normals;
  if (triangles_.empty()) return;
  add_triangle_pieces();
  add_user_geometry(kTriangles, pieces_.size(), EmbreeCallbacks::triangle_bounds,
                    EmbreeCallbacks::intersect_triangles, EmbreeCallbacks::occluded_triangles);
}

void EmbreeScene::add_triangle_pieces() {
  std::vector<uint8_t> counts(triangles_.size());
  size_t total = 0;
  for (size_t t = 0; t < triangles_.size(); ++t) {
    const LocalTriangle& tri = triangles_[t];
    counts[t] = static_cast<uint8_t>(triangle_piece_count(tri.a, tri.b, tri.c));
    total += counts[t];
  }
  piece_boxes_.reserve(total);
  pieces_.reserve(total);
  for (uint32_t t = 0; t < triangles_.size(); ++t) {
    const LocalTriangle& tri = triangles_[t];
    if (t + 1 < triangles_.size() && counts[t] == 1 && counts[t + 1] == 1) {
      const LocalTriangle& next = triangles_[t + 1];
      const Box both = box_of({tri.a, tri.b, tri.c, next.a, next.b, next.c});
      if (worth_pairing(both, box_of({tri.a, tri.b, tri.c}), box_of({next.a, next.b, next.c}))) {
        piece_boxes_.push_back(both);
        pieces_.push_back({t++, 2});
        continue;
      }
    }
    const int added = append_triangle_pieces(tri.a, tri.b, tri.c, counts[t], piece_boxes_);
    pieces_.insert(pieces_.end(), static_cast<size_t>(added), TrianglePiece{t, 1});
  }
}

void EmbreeScene::add_spheres(const Scene& scene) {
  if (scene.spheres.empty()) return;
  for (const Sphere& s : scene.spheres) {
    spheres_.push_back({to_local(s.center), std::fabs(s.radius)});
    materials_[kSpheres].push_back(material_of(scene, s.material));
  }
  add_user_geometry(kSpheres, spheres_.size(), EmbreeCallbacks::sphere_bounds,
                    EmbreeCallbacks::intersect_spheres, EmbreeCallbacks::occluded_spheres);
}

void EmbreeScene::add_cones(const Scene& scene) {
  // User geometry over intersect_cone(). (Embree's RTC_GEOMETRY_TYPE_CONE_LINEAR_CURVE
  // with both neighbour flags set, the way to suppress its end caps, clips each
  // segment against its neighbours' vertices; NFF cones are independent segments,
  // and rings-7 rendered that way came out wrong, +10% reflection rays.)
  if (scene.cones.empty()) return;
  for (const Cone& c : scene.cones) {
    const ConeShape shape = ConeShape::make(to_local(c.base), c.base_radius, to_local(c.apex), c.apex_radius);
    // Slices at most eight radii long, at most kMaxSlices; the first and last
    // are open-ended so the cone's own end test applies there. Rings' tubes
    // are 15 radii long; against four slices each (four radii), two took
    // 0.97x the time, eight 1.08x and one 1.05x: tighter boxes save cone
    // tests until the walk over more slices costs more than they save.
    // Again with packets and the cone kernel (7 pairs): four took 1.07x the
    // time of two, and one 1.06x.
    constexpr int kMaxSlices = 8;
    const double len = 2 * shape.half_length, r = std::max(shape.max_radius(), 1e-300);
    const int n = std::clamp(static_cast<int>(std::ceil(len / (8 * r))), 1, kMaxSlices);
    const auto first = static_cast<uint32_t>(cone_slices_.size());
    for (int i = 0; i < n; ++i) {
      const double lo = i == 0 ? -HUGE_VAL : -shape.half_length + len * i / n;
      const double hi = i == n - 1 ? HUGE_VAL : -shape.half_length + len * (i + 1) / n;
      cone_slices_.push_back({shape, lo, hi});
      cone_spans_.push_back({first, static_cast<uint32_t>(n)});
      materials_[kCones].push_back(material_of(scene, c.material));
    }
  }
  add_user_geometry(kCones, cone_slices_.size(), EmbreeCallbacks::cone_bounds,
                    EmbreeCallbacks::intersect_cones, EmbreeCallbacks::occluded_cones);
}

namespace {
void set_ray(RTCRay& ray, const FloatRay& from, float tfar) {
  ray.org_x = from.org[0];
  ray.org_y = from.org[1];
  ray.org_z = from.org[2];
  ray.dir_x = from.dir[0];
  ray.dir_y = from.dir[1];
  ray.dir_z = from.dir[2];
  ray.tnear = 0.0f;
  ray.tfar = tfar;
  ray.mask = 0xFFFFFFFFu;
  ray.flags = 0;
  ray.time = 0;
  ray.id = 0;
}
}  // namespace

void EmbreeScene::Query::fill_packet(const LaneKernels& kernels, RTCRay16& rays, int* valid, RayLanes& soa,
                                     const Vec3* orgs, const Vec3* dirs, int count, double tfar,
                                     const Departure* departures) {
  alignas(64) FloatLanes floats;
  fill_checked(kernels, orgs, dirs, count, tfar, soa, floats);
  std::memcpy(rays.org_x, floats.org[0], sizeof rays.org_x);
  std::memcpy(rays.org_y, floats.org[1], sizeof rays.org_y);
  std::memcpy(rays.org_z, floats.org[2], sizeof rays.org_z);
  std::memcpy(rays.dir_x, floats.dir[0], sizeof rays.dir_x);
  std::memcpy(rays.dir_y, floats.dir[1], sizeof rays.dir_y);
  std::memcpy(rays.dir_z, floats.dir[2], sizeof rays.dir_z);
  const float far = static_cast<float>(tfar);
  for (int i = 0; i < kPacket; ++i) {
    valid[i] = -1;
    rays.tnear[i] = 0.0f;
    if (i >= count) disable_lane(rays, valid, i);
    rays.tfar[i] = far;
    rays.mask[i] = 0xFFFFFFFFu;
    rays.flags[i] = 0;
    rays.time[i] = 0;
    rays.id[i] = static_cast<unsigned>(i);  // the callbacks' index into lanes
    lanes[i].tfar = tfar;
    lanes[i].best.geom = RTC_INVALID_GEOMETRY_ID;
    lanes[i].best.t = HUGE_VAL;
  }
  departing.set(departures, count);
  packet = &soa;
  rays_set = 0;
}

bool EmbreeScene::intersect(const Vec3& org, const Vec3& dir, TraceHit& hit, const Departure& departure) const {
  Query::Lane lane;
  Query query(&lane);
  const FloatRay ray(org, dir);
  query.set_lane(ray.exact(), HUGE_VAL, departure);
  RTCRayHit rh;
  set_ray(rh.ray, ray, __builtin_huge_valf());
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  rtcIntersect1(scene_, &query.context, &rh);
  if (lane.best.geom == RTC_INVALID_GEOMETRY_ID) return false;
  hit = lane.best;
  return true;
}

// Embree's frustum walk pays for eye rays, and costs for mirror and
// refraction rays, which diverge: against every packet through it, the
// per-ray walk for those took 0.90x the render time on balls, 0.98x on mount
// and 1.01x on gears (9 pairs each); eye rays through the per-ray walk too
// made mount 1.3x slower. Mirror and refraction rays that start far apart
// go one by one (kScatteredShare).
void EmbreeScene::intersect_packet(const Vec3* orgs, const Vec3* dirs, int count, TraceHit* hits,
                                   Origins origins, const Departure* departures, const uint32_t* inside) const {
  // Rays all said to start inside one sphere whose interior is listed skip the walk.
  if (inside && count > 1 && inside[0] < interior_of_.size() && interior_of_[inside[0]] != kNotListed &&
      std::all_of(inside + 1, inside + count, [&](uint32_t s) { return s == inside[0]; })) {
    assert(!departures || std::all_of(departures, departures + count,
                                      [](const Departure& d) { return d.geom == Departure::kNone; }));
    return intersect_inside(inside[0], orgs, dirs, count, hits);
  }
  if (count == 1 || (origins == Origins::kScattered && box_width2(orgs, count) > scattered_width2_)) {
    const Departure none;
    for (int i = 0; i < count; ++i) {
      if (!intersect(orgs[i], dirs[i], hits[i], departures ? departures[i] : none)) {
        hits[i].geom = RTC_INVALID_GEOMETRY_ID;
      }
    }
    return;
  }
  alignas(64) RTCRayHit16 packet;
  alignas(64) int valid[kPacket];
  // Kept per thread: built on every call, the 16 lanes' default members cost
  // 3% of tetra's time, and fill_packet() sets what a packet reads.
  thread_local Query::Lane lanes[kPacket];
  Query query(lanes);
  query.context.flags = origins == Origins::kOnePoint ? RTC_INTERSECT_CONTEXT_FLAG_COHERENT
                                                      : RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT;
  thread_local RayLanes soa;
  query.fill_packet(lane_kernels_, packet.ray, valid, soa, orgs, dirs, count, HUGE_VAL, departures);
  for (int i = 0; i < kPacket; ++i) {
    packet.hit.geomID[i] = RTC_INVALID_GEOMETRY_ID;
    packet.hit.instID[0][i] = RTC_INVALID_GEOMETRY_ID;
  }
  rtcIntersect16(valid, scene_, &query.context, &packet);
  for (int i = 0; i < count; ++i) hits[i] = lanes[i].best;
}

void EmbreeScene::fill_lanes(const Vec3* orgs, const Vec3* dirs, int count, double tfar, RayLanes& soa,
                             FloatLanes& floats) const {
  fill_checked(lane_kernels_, orgs, dirs, count, tfar, soa, floats);
}

// The hits of `o` on the `lanes` of `soa`, made theirs in `hits` where the
// tie rule says they are nearer (intersect_inside()).
void EmbreeScene::meet_intruder(const Occluder& o, const RayLanes& soa, uint32_t lanes, TraceHit* hits) const {
  Query::Lane best[kPacket];
  Query query(best);
  query.packet = &soa;
  for (uint32_t bits = lanes; bits; bits &= bits - 1) best[__builtin_ctz(bits)].best = hits[__builtin_ctz(bits)];
  EmbreeCallbacks::keep_nearer_hits(*this, query, o.geom, o.prim, lanes, [](int, double) {});
  for (uint32_t bits = lanes; bits; bits &= bits - 1) hits[__builtin_ctz(bits)] = best[__builtin_ctz(bits)].best;
}

// The lanes of `soa` (as bits, of `active`) that `o` blocks, from the lane
// kernel of its kind; the lanes of `query` that depart `o` are left out.
uint32_t EmbreeScene::blocks(const Occluder& o, const RayLanes& soa, uint32_t active, const Query& query) const {
  if (o.geom == RTC_INVALID_GEOMETRY_ID) return 0;  // no blocker yet
  active &= ~query.departing.skipping(o.geom, o.prim);
  if (!active) return 0;
  if (o.geom == kTriangles) {
    return EmbreeCallbacks::piece_blocks(*this, soa, active, pieces_[o.prim]);
  }
  if (o.geom == kSpheres) {
    alignas(64) double t[RayLanes::kLanes];
    return EmbreeCallbacks::sphere_lanes(*this, soa, active, spheres_[o.prim], t);
  }
  if (o.geom == kCones) {
    ConeLaneHits hits;
    return EmbreeCallbacks::cone_lanes(*this, soa, active, o.prim, hits);
  }
  return 0;
}

// The lanes of `soa` (of `active`) that the cache's blockers block; the
// second becomes the first when it blocks lanes and the first none.
uint32_t EmbreeScene::cached_blocks(ShadowCache& cache, const RayLanes& soa, uint32_t active,
                                    const Query& query) const {
  const uint32_t first = blocks(cache.first, soa, active, query);
  if (first == active) return first;
  const uint32_t second = blocks(cache.second, soa, active & ~first, query);
  if (second && !first) std::swap(cache.first, cache.second);
  return first | second;
}

bool EmbreeScene::occluded_single(const Vec3& org, const Vec3& dir, double tfar, ShadowCache* cache,
                                  const Departure& departure) const {
  const FloatRay held(org, dir);
  const ShearedRay exact = held.exact();
  if (cache && cached_blocks(*cache, exact, tfar, departure)) return true;
  RTCRay ray;
  set_ray(ray, held, float_at_least(tfar));
  return walk_occluded(ray, exact, tfar, cache, departure);
}

// The single-ray walk of `ray` (as Embree holds it; `exact` its twin in
// double); a blocker it finds goes into `cache`.
bool EmbreeScene::walk_occluded(RTCRay& ray, const ShearedRay& exact, double tfar, ShadowCache* cache,
                                const Departure& departure) const {
  Query::Lane lane;
  Query query(&lane);
  query.set_lane(exact, tfar, departure);
  rtcOccluded1(scene_, &query.context, &ray);
  if (ray.tfar >= 0) return false;
  if (cache) cache->remember(query.found);
  return true;
}

namespace {

// Whether shadow rays org + t dir, t in (0, 1), start so far apart that
// Embree's frustum walk, which hands a leaf every ray still active in the
// packet, costs more than a walk per ray: their origins' box is wider than
// kSpreadRatio of the nearest origin's distance to the light. Rings' deep
// shadow rays leave tubes all over the scene: in packets, 83-87% of the rays
// handed to a cone's test from the second level on missed even its box, and
// a walk per ray took 0.89x the whole process's time (7 pairs). Ratios from
// 0.03 to 0.6 rendered rings alike, 1.2 slower. Gears' and mount's mirror
// hits, on flat facets, stay close (at 0.3, 1,480 of gears' 1.57M shadow
// packets are spread, none of mount's 419k); walked ray by ray from the
// second level on whether spread or not, they rendered 1.15x and 1.22x
// slower (instrumented builds, 5 runs each).
constexpr double kSpreadRatio = 0.3;

bool spread_out(const Vec3* orgs, const Vec3* dirs, int count) {
  double nearest2 = dot(dirs[0], dirs[0]);
  for (int i = 1; i < count; ++i) nearest2 = std::min(nearest2, dot(dirs[i], dirs[i]));
  return box_width2(orgs, count) > kSpreadRatio * kSpreadRatio * nearest2;
}

}  // namespace

bool EmbreeScene::walks_alone(const Vec3* orgs, const Vec3* dirs, int count, Origins found_by) const {
  return count == 1 || (found_by == Origins::kScattered && spread_out(orgs, dirs, count));
}

// Ray by ray through the single-ray walk, after the rays' caches, which are
// tested for all the rays at once (cached_blocks_apart()). Asked ray by ray,
// each cache test's divisions and square root held up the ray behind it
// (about 100 cycles a test on rings); in lanes, rings renders in 0.956x the
// time (21 pairs). For a lone ray in the walk, the lane kernels took 1.03x
// the time of the scalar tests, which the walk still runs.
void EmbreeScene::occluded_alone(const Vec3* orgs, const Vec3* dirs, int count, bool* blocked,
                                 ShadowCache* const* caches, const Departure* departures) const {
  assert(count <= kPacket);
  alignas(64) FloatLanes floats;
  thread_local RayLanes soa;  // as in intersect_packet()
  fill_checked(lane_kernels_, orgs, dirs, count, 1.0, soa, floats);
  Occluder tested[kPacket];  // each ray's first cache entry, as tested
  for (int i = 0; i < count; ++i) tested[i] = caches[i] ? caches[i]->first : Occluder{};
  const uint32_t cached = cached_blocks_apart(caches, soa, count, departures);
  const Departure none;
  for (int i = 0; i < count; ++i) {
    blocked[i] = (cached >> i) & 1;
    if (blocked[i]) continue;
    const Departure& departure = departures ? departures[i] : none;
    const ShearedRay exact = lane_ray(soa, i);
    // An earlier ray's walk may have put a new blocker first in a shared cache.
    if (caches[i] && !(caches[i]->first == tested[i]) && blocks(caches[i]->first, exact, 1.0, departure)) {
      blocked[i] = true;
      continue;
    }
    RTCRay ray;
    set_ray(ray, FloatRay(floats, i), float_at_least(1.0));
    blocked[i] = walk_occluded(ray, exact, 1.0, caches[i], departure);
  }
}

void EmbreeScene::occluded_together(const Vec3* orgs, const Vec3* dirs, int count, bool* blocked,
                                    ShadowCache* cache, const Departure* departures) const {
  alignas(64) RTCRay16 packet;
  alignas(64) int valid[kPacket];
  thread_local Query::Lane lanes[kPacket];  // as in intersect_packet()
  Query query(lanes);
  // Shadow rays of nearby hits converge on their light: the frustum walk
  // pays for them (the per-ray walk made gears, five lights, 1.07x slower).
  query.context.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
  thread_local RayLanes soa;  // as lanes
  query.fill_packet(lane_kernels_, packet, valid, soa, orgs, dirs, count, 1.0, departures);
  // The shadow cache, for all lanes at once, and only the lanes it leaves
  // go to Embree: on gears the blocker of the light's previous packet
  // blocked a quarter of all shadow rays, and every ray of one packet in six.
  const uint32_t all = (1u << count) - 1;
  const uint32_t cached = cache ? cached_blocks(*cache, soa, all, query) : 0;
  if (cached != all) {
    for (uint32_t bits = cached; bits; bits &= bits - 1) disable_lane(packet, valid, __builtin_ctz(bits));
    rtcOccluded16(valid, scene_, &query.context, &packet);
    if (cache && query.found.geom != RTC_INVALID_GEOMETRY_ID) cache->remember(query.found);
  }
  // Lanes Embree did not walk keep fill_packet()'s tfar (1): not negative.
  const uint32_t found = negative_lanes(packet.tfar);
  for (int i = 0; i < count; ++i) blocked[i] = ((cached | found) >> i) & 1;
}

}  // namespace rayfarm
