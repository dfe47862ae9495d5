// EmbreeScene: the one place that owns the Embree device and RTCScene.
// Built once from a Scene, camera-relative: every position has the camera's
// `from` subtracted in double, so a scene moved far from the origin traces
// exactly like the original. Every primitive -- sphere, cone slice, and the
// triangles polygons are ear-clipped into -- is Embree user geometry over the
// double-precision tests of shapes.h: Embree only builds the BVH and walks it,
// and never computes a hit. That makes pixels independent of the SIMD width
// Embree picks for the CPU (SSE4.2 .. AVX-512 walk BVH4 or BVH8 in different
// orders, and their float triangle kernels round differently): see Query in
// embree_scene.cpp for the tie rule and why no candidate is culled. It costs
// time where Embree's SIMD float triangle kernels did the work; a packet's
// rays go through the triangle, sphere and cone tests together in SIMD lanes
// (lane_kernels.h, same bits), long thin triangles go to Embree as
// several tighter pieces (triangle_pieces.h), as Embree's own spatial splits
// would have cut them, and two neighbours that share most of a box as one.
// The hot
// path asks intersect()/occluded() for single rays, intersect_packet() for up
// to 16 rays, and for up to 16 shadow rays walks_alone(), then
// occluded_together() with the light's shadow cache or occluded_alone() with
// a cache per ray (occluded_packet() makes that choice for one cache).
#pragma once

#include <embree3/rtcore.h>

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "tracer/box.h"
#include "tracer/departure.h"
#include "tracer/lane_kernels.h"
#include "tracer/scene.h"
#include "tracer/shapes.h"
#include "tracer/triangle_pieces.h"
#include "tracer/vec3.h"

namespace rayfarm {

// Embree's kernel families, narrowest first; `EmbreeOptions::max_isa` caps the
// one Embree picks for this CPU (its device option of the same name).
inline constexpr const char* kEmbreeIsas[] = {"sse2", "sse4.2", "avx", "avx2", "avx512"};
// Throws InputError "`where`: max_isa must be ..." unless `isa` is "" (no cap)
// or one of kEmbreeIsas.
void check_embree_isa(const std::string& isa, const std::string& where);

struct EmbreeOptions {
  std::string max_isa;           // "" = the widest this CPU runs, else one of kEmbreeIsas
  bool robust_bvh = false;       // RTC_SCENE_FLAG_ROBUST
  bool high_quality = true;      // RTC_BUILD_QUALITY_HIGH (slower build, faster traversal)
};

// A closest hit in camera-relative coordinates.
struct TraceHit {
  double t = 0;
  Vec3 ng;  // geometric normal, unnormalised; outward for spheres/cones,
            // the polygon's right-handed (counter-clockwise) normal for polygons
  uint32_t geom = 0, prim = 0;
  double u = 0, v = 0;  // triangle barycentrics (hit = (1-u-v) v0 + u v1 + v v2)
};

class EmbreeScene {
 public:
  // Geometry IDs, fixed so lookups need no table.
  enum Kind : uint32_t { kTriangles = 0, kSpheres = 1, kCones = 2, kKinds = 3 };

  EmbreeScene(const Scene& scene, const EmbreeOptions& options);
  ~EmbreeScene();
  EmbreeScene(const EmbreeScene&) = delete;
  EmbreeScene& operator=(const EmbreeScene&) = delete;

  // World position of the local origin (the camera's `from`).
  const Vec3& origin() const { return origin_; }
  Vec3 to_local(const Vec3& world) const { return world - origin_; }

  using Departure = rayfarm::Departure;  // departure.h
  // The departure of a ray that leaves `hit` from the outside (the hit's
  // ray arrived against its outward normal) and goes away from it.
  Departure departure_from(const TraceHit& hit) const {
    if (hit.geom == kSpheres) return {kSpheres, hit.prim, 1};
    if (hit.geom == kCones) return {kCones, cone_spans_[hit.prim].first, cone_spans_[hit.prim].count};
    return {};
  }

  // The box that holds every primitive, camera-relative: Embree's root
  // bounds, around every primitive's widened box, so a ray that misses it
  // meets nothing. lo lies above hi for a scene without primitives.
  void bounds(Vec3& lo, Vec3& hi) const;
  // Hands `visit` points around each primitive, camera-relative: a
  // triangle's three corners, a sphere's or cone slice's box's eight
  // (widened by as much as Embree's are). Every hit an exact test can
  // report lies in the convex hull of one primitive's points, but for the
  // rounding of its distance along the ray. Stops when `visit` returns false.
  void for_each_hull(const std::function<bool(const Vec3* points, int count)>& visit) const;

  // Closest hit of org + t*dir for t in (0, inf); false on a miss. Ties in t
  // go to the lowest (geom, prim), see embree_scene.cpp.
  bool intersect(const Vec3& org, const Vec3& dir, TraceHit& hit, const Departure& departure = {}) const;

  // Whether anything lies on org + t*dir for t in (0, tfar).
  bool occluded(const Vec3& org, const Vec3& dir, double tfar, const Departure& departure = {}) const {
    return occluded_single(org, dir, tfar, nullptr, departure);
  }

  // Haines' shadow cache (the "last occluder" of a light), two deep: the
  // primitives that last blocked shadow rays towards that light are tested
  // first, by the same exact test Embree's callbacks run, and a ray they
  // block skips the BVH. The cache changes no result: "blocked" is that
  // exact test, whoever finds it. Shadow rays walked one by one keep one per
  // primitive they start on instead (start_shadow_caches.h).
  struct Occluder {
    uint32_t geom = RTC_INVALID_GEOMETRY_ID, prim = 0;
    bool operator==(const Occluder& o) const { return geom == o.geom && prim == o.prim; }
  };
  struct ShadowCache {
    Occluder first, second;  // the one that blocked most recently first
    // A blocker the BVH found becomes the first; the first moves down.
    void remember(const Occluder& found) {
      if (found == first) return;
      second = first;
      first = found;
    }
  };

  // Where a packet's rays start: all at one point (eye rays), or on surfaces
  // (mirror and refraction rays). Only time depends on it: packets go through
  // Embree's 16-wide walk, flagged RTC_INTERSECT_CONTEXT_FLAG_COHERENT or
  // INCOHERENT (for user geometry Embree walks the packet as a whole either
  // way), and mirror and refraction rays whose origins lie far apart in the
  // scene go one by one through its single-ray walk, see intersect_packet().
  enum class Origins { kOnePoint, kScattered };

  // Up to kPacket coherent rays (e.g. neighbouring eye rays) at once, t in (0, inf).
  // `hits[i].geom` is RTC_INVALID_GEOMETRY_ID for a miss. A single ray takes
  // the single-ray path, so results depend only on the rays passed together.
  // `departures` (optional): ray i's departure. `inside` (optional): the
  // sphere (primID) ray i starts inside, or kNoSphere: a hint, checked ray
  // by ray, that lets a packet inside one sphere skip the walk
  // (intersect_inside()); only time depends on it.
  static constexpr int kPacket = 16;
  static constexpr uint32_t kNoSphere = UINT32_MAX;
  void intersect_packet(const Vec3* orgs, const Vec3* dirs, int count, TraceHit* hits,
                        Origins origins = Origins::kScattered, const Departure* departures = nullptr,
                        const uint32_t* inside = nullptr) const;
  // Up to kPacket shadow rays org + t*dir, t in (0, 1); blocked[i] = occluded.
  // `cache` (optional) is the light's shadow cache, read and updated.
  // `found_by` says how the rays that found the origins started: the hits of
  // eye rays (kOnePoint) lie side by side and take the frustum walk; the hits
  // of mirror and refraction rays (kScattered) may lie far apart, and when
  // they do (spread_out() in embree_scene.cpp) each ray takes Embree's
  // single-ray walk. Only time depends on it.
  void occluded_packet(const Vec3* orgs, const Vec3* dirs, int count, bool* blocked,
                       ShadowCache* cache = nullptr, Origins found_by = Origins::kOnePoint) const {
    assert(count <= kPacket);
    if (walks_alone(orgs, dirs, count, found_by)) {
      ShadowCache* caches[kPacket];
      std::fill(caches, caches + count, cache);
      occluded_alone(orgs, dirs, count, blocked, caches);
    } else {
      occluded_together(orgs, dirs, count, blocked, cache);
    }
  }
  // The two halves of occluded_packet(), for callers that choose each ray's
  // cache. Whether its rays take the single-ray walk, one by one:
  bool walks_alone(const Vec3* orgs, const Vec3* dirs, int count, Origins found_by) const;
  // One by one, ray i with its cache `caches[i]` (null: none); the caches
  // are asked for all the rays before the first walk. `departures`
  // (optional) as for intersect_packet(), here and below.
  void occluded_alone(const Vec3* orgs, const Vec3* dirs, int count, bool* blocked, ShadowCache* const* caches,
                      const Departure* departures = nullptr) const;
  // All at once, through the frustum walk, with the light's cache.
  void occluded_together(const Vec3* orgs, const Vec3* dirs, int count, bool* blocked, ShadowCache* cache,
                         const Departure* departures = nullptr) const;

  // How many primitives reach into sphere `sphere` (a primID), as its
  // inside rays meet them without a walk; -1 when its inside rays walk (an
  // opaque sphere, or one too many primitives reach into).
  int intruder_count(uint32_t sphere) const {
    if (sphere >= interior_of_.size() || interior_of_[sphere] == kNotListed) return -1;
    return interiors_[interior_of_[sphere]].shape.caps;
  }

  // A number no other EmbreeScene of this process has: what per-thread state
  // keyed by primitive (StartShadowCaches) knows its scene by.
  uint64_t serial() const { return serial_; }

  // How many primitives of a kind Embree holds (hits' prim below this):
  // triangles, spheres, cone slices.
  size_t primitive_count(Kind kind) const { return materials_[kind].size(); }
  uint32_t material(const TraceHit& hit) const { return materials_[hit.geom][hit.prim]; }

  // The barycentric blend of a `pp` patch's vertex normals at the hit, or false
  // when the hit primitive has none.
  bool vertex_normal(const TraceHit& hit, Vec3& normal) const {
    if (hit.geom != kTriangles || smooth_.empty() || !smooth_[hit.prim]) return false;
    const uint32_t* tri = &indices_[3 * size_t(hit.prim)];
    const double u = hit.u, v = hit.v;
    normal = (1 - u - v) * normals_[tri[0]] + u * normals_[tri[1]] + v * normals_[tri[2]];
    return true;
  }

  // The lane kernels of this scene's width (EmbreeOptions::max_isa), for
  // shading's hit-frame kernel too.
  const LaneKernels& kernels() const { return lane_kernels_; }

  double build_seconds() const { return build_seconds_; }
  size_t triangle_count() const { return indices_.size() / 3; }

  // Embree's ray.valid() -- an assertion in Debian's build, so a process
  // abort -- needs every origin and direction component within FLT_LARGE
  // (kMaxRayComponent) and not NaN. Scene numbers are bounded
  // (kMaxSceneMagnitude), but degenerate geometry at large scales can still
  // make NaN or huge rays; they fail the render with an InputError here
  // instead of killing the process. (Packets: the fill kernel tests the same.)
  static void check_ray(const Vec3& org, const Vec3& dir) {
    constexpr double kLimit = kMaxRayComponent;
    const bool valid = std::abs(org.x) <= kLimit && std::abs(org.y) <= kLimit && std::abs(org.z) <= kLimit &&
                       std::abs(dir.x) <= kLimit && std::abs(dir.y) <= kLimit && std::abs(dir.z) <= kLimit;
    if (__builtin_expect(!valid, 0)) throw_invalid_ray(org, dir);
  }
  [[noreturn]] static void throw_invalid_ray(const Vec3& org, const Vec3& dir);

 private:
  struct Query;  // per-call state of the callbacks, see embree_scene.cpp
  bool occluded_single(const Vec3& org, const Vec3& dir, double tfar, ShadowCache* cache,
                       const Departure& departure) const;
  bool blocks(const Occluder& o, const ShearedRay& exact, double tfar, const Departure& departure) const;
  uint32_t blocks(const Occluder& o, const RayLanes& soa, uint32_t active, const Query& query) const;
  bool cached_blocks(ShadowCache& cache, const ShearedRay& exact, double tfar, const Departure& departure) const;
  uint32_t cached_blocks(ShadowCache& cache, const RayLanes& soa, uint32_t active, const Query& query) const;
  uint32_t blocks_apart(const Occluder* occluders, uint32_t lanes, const RayLanes& soa,
                        const Departure* departures) const;
  uint32_t cached_blocks_apart(ShadowCache* const* caches, const RayLanes& soa, int count,
                               const Departure* departures) const;
  bool walk_occluded(RTCRay& ray, const ShearedRay& exact, double tfar, ShadowCache* cache,
                     const Departure& departure) const;
  // Rays inside a sphere (Interior; sphere_interiors.cpp): find_interiors()
  // lists what reaches into each glass sphere, once, after the build, and
  // set_cap() the cap of `sphere` that `o` reaches into; intersect_inside()
  // is intersect_packet() for rays [0, count) said to start inside
  // `sphere`, which has an Interior, departing nothing; meet_intruder()
  // keeps the hits of `o` on some of its lanes that are nearer.
  void find_interiors(const Scene& scene);
  void set_cap(uint32_t sphere, const Occluder& o, double slack, double* axis, double& level) const;
  void intersect_inside(uint32_t sphere, const Vec3* orgs, const Vec3* dirs, int count, TraceHit* hits) const;
  void meet_intruder(const Occluder& o, const RayLanes& soa, uint32_t lanes, TraceHit* hits) const;
  // The fill kernel's lanes of rays 0..count-1; throws for a ray Embree
  // cannot take (check_ray()).
  void fill_lanes(const Vec3* orgs, const Vec3* dirs, int count, double tfar, RayLanes& soa,
                  FloatLanes& floats) const;

  // The exact test of one primitive (shapes.h) on a ray, t in (0, tfar): what
  // the callbacks and the shadow cache run. `prim` is Embree's primID (for
  // triangles a piece, for cones a slice); a triangle hit's `out.prim` is the
  // triangle, as materials and `pp` normals index them.
  bool hit_triangle(uint32_t prim, const ShearedRay& r, double tfar, TraceHit& out) const;
  bool hit_sphere(uint32_t prim, const ShearedRay& r, double tfar, TraceHit& out) const;
  bool hit_cone(uint32_t prim, const ShearedRay& r, double tfar, TraceHit& out) const;
  bool hit_primitive(uint32_t geom, uint32_t prim, const ShearedRay& r, double tfar, TraceHit& out) const;
  // The boxes of a sphere and of a cone slice (before widening).
  Box sphere_box(uint32_t prim) const;
  Box slice_box(uint32_t prim) const;

  void add_user_geometry(uint32_t id, size_t count, RTCBoundsFunction bounds, RTCIntersectFunctionN intersect,
                         RTCOccludedFunctionN occluded);
  void add_triangles(const Scene& scene);
  void add_triangle_pieces();  // piece_boxes_ and pieces_ for triangles_
  void add_spheres(const Scene& scene);
  void add_cones(const Scene& scene);
  void check_error(const char* what) const;

  Vec3 origin_;
  uint64_t serial_;
  RTCDevice device_ = nullptr;
  RTCScene scene_ = nullptr;
  RTCBuildQuality quality_ = RTC_BUILD_QUALITY_MEDIUM;
  double build_seconds_ = 0;
  mutable std::string error_;  // first message from the device error callback

  std::vector<uint32_t> materials_[kKinds];  // per primitive of each kind
  // Boxes handed to Embree are widened by this much on every side: enough that
  // float ray/box tests of any kernel width surely enter the box of every
  // primitive a ray meets (see box_margin() in embree_scene.cpp).
  double box_margin_ = 0;
  // Squared width of an origins' box beyond which a packet's mirror or
  // refraction rays go one by one (see kScatteredShare in embree_scene.cpp).
  double scattered_width2_ = HUGE_VAL;
  LaneKernels lane_kernels_;  // for this CPU and max_isa
  // Triangles, camera-relative, their right-handed normals (b-a) x (c-a) (apart:
  // only hits read them), and their scene vertex indices (for `pp` normals).
  struct LocalTriangle {
    Vec3 a, b, c;
  };
  std::vector<LocalTriangle> triangles_;
  // What Embree sees of the triangles: pieces, each testing `count`
  // triangles from `first`: a triangle, one of the several pieces of a long
  // thin one, or two neighbours (triangle_pieces.h: worth_pairing()). A triangle's
  // primID is its piece; its hits name the triangle. The boxes are freed
  // once the BVH is built.
  struct TrianglePiece {
    uint32_t first, count;
  };
  std::vector<TrianglePiece> pieces_;
  std::vector<Box> piece_boxes_;
  std::vector<Vec3> triangle_normals_;
  std::vector<uint32_t> indices_;
  std::vector<uint8_t> smooth_;  // per triangle: has `pp` vertex normals
  std::vector<Vec3> normals_;    // per scene vertex (`pp` only)
  // Curved primitives, camera-relative.
  struct LocalSphere {
    Vec3 center;
    double radius;
  };
  std::vector<LocalSphere> spheres_;
  // Cones are handed to Embree as slices along their axis (tighter boxes for
  // long thin tubes at any angle); a cone hit's primID is its slice. Each
  // slice holds its cone, so a test makes one memory access, not two in a row.
  struct ConeSlice {
    ConeShape shape;
    double s_lo, s_hi;  // see intersect_cone()
  };
  std::vector<ConeSlice> cone_slices_;
  static ConeLaneShape cone_lane_shape(const ConeSlice& s);  // as the cone kernels take a slice
  // Per slice, the slices of its cone (a Departure), apart: the tests never read them.
  struct SliceSpan {
    uint32_t first, count;
  };
  std::vector<SliceSpan> cone_spans_;

  // A ray that starts inside a sphere meets nothing before it leaves the
  // sphere but the primitives that reach into it (mount's glass spheres:
  // the neighbours that touch them). Per sphere a ray can be inside (its
  // material transmits), those primitives, found once, when few enough,
  // each with the cap of the sphere it can be met in (find_interiors()).
  struct Interior {
    InteriorLaneShape shape;  // the sphere, its reach and its intruders' caps
    Occluder intruders[InteriorLaneShape::kMaxCaps];  // cap k's (kind, primID)
  };
  static constexpr uint32_t kNotListed = UINT32_MAX;
  std::vector<uint32_t> interior_of_;  // per sphere: its Interior, or kNotListed; empty: no sphere transmits
  std::vector<Interior> interiors_;

  friend struct EmbreeCallbacks;
};

}  // namespace rayfarm
