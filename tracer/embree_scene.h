// EmbreeScene: the one place that owns the Embree device and RTCScene.
// Built once from a Scene, camera-relative: every position has the camera's
// `from` subtracted in double before it is rounded to float, so a scene moved
// far from the origin traces exactly like the original. Spheres and cones are
// user geometry over the analytic double-precision solvers in shapes.h; for
// spheres Embree's built-in float sphere points are an option, but measured on
// balls-4, mount-6 and rings-7 (16 spp, packets, one core) they render 10-13%
// slower. Polygons are ear-clipped into one triangle mesh. The hot path asks
// intersect()/occluded() for single rays and intersect_packet()/occluded_packet()
// for up to 16 coherent rays (traced one by one in cone-heavy scenes, where
// Embree's packets are slower), with a per-light shadow cache.
#pragma once

#include <embree3/rtcore.h>

#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "tracer/scene.h"
#include "tracer/shapes.h"
#include "tracer/vec3.h"

namespace rayfarm {

struct EmbreeOptions {
  bool robust_bvh = false;       // RTC_SCENE_FLAG_ROBUST
  bool builtin_spheres = false;  // RTC_GEOMETRY_TYPE_SPHERE_POINT instead of user geometry
  bool high_quality = true;      // RTC_BUILD_QUALITY_HIGH (slower build, faster traversal)
};

// A closest hit in camera-relative coordinates.
struct TraceHit {
  double t = 0;
  Vec3 ng;  // geometric normal, unnormalised; outward for spheres/cones,
            // the polygon's right-handed (counter-clockwise) normal for polygons
  uint32_t geom = 0, prim = 0;
  float u = 0, v = 0;  // triangle barycentrics (hit = (1-u-v) v0 + u v1 + v v2)
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

  // Closest hit of org + t*dir for t in (0, inf); false on a miss.
  bool intersect(const Vec3& org, const Vec3& dir, TraceHit& hit) const {
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    RTCRayHit rh;
    set_ray(rh.ray, org, dir, 0.0f, kInfinity);
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(scene_, &context, &rh);
    if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return false;
    read_hit(rh.ray.tfar, rh.hit, hit);
    return true;
  }

  // Whether anything lies on org + t*dir for t in (0, tfar).
  bool occluded(const Vec3& org, const Vec3& dir, float tfar) const {
    return occluded_single(org, dir, tfar, nullptr);
  }

  // Haines' shadow cache (the "last occluder" of a light): the sphere or cone
  // that last blocked a shadow ray towards that light is tested first, by the
  // same exact solver Embree's callbacks run, and a ray it blocks skips the
  // BVH. Only curved primitives are remembered (triangle tests are Embree's
  // own). The cache changes no result (short of a grazing ray that Embree's
  // float box tests would have missed), and callers keep one per pixel so that
  // even that depends on the pixel alone.
  struct Occluder {
    uint32_t geom = RTC_INVALID_GEOMETRY_ID, prim = 0;
  };

  // Up to kPacket coherent rays (e.g. one pixel's samples) at once, t in (0, inf).
  // `hits[i].geom` is RTC_INVALID_GEOMETRY_ID for a miss. A single ray takes
  // the single-ray path, so results depend only on the rays passed together;
  // so do all rays of a scene where packets do not pay (uses_packets()).
  static constexpr int kPacket = 16;
  void intersect_packet(const Vec3* orgs, const Vec3* dirs, int count, TraceHit* hits) const;
  // Up to kPacket shadow rays org + t*dir, t in (0, 1); blocked[i] = occluded.
  // `last` (optional) is the light's shadow cache, read and updated.
  void occluded_packet(const Vec3* orgs, const Vec3* dirs, int count, bool* blocked,
                       Occluder* last = nullptr) const;

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

  // Whether intersect_packet()/occluded_packet() use Embree's packet traversal
  // (chosen from the scene's make-up, see the constructor).
  bool uses_packets() const { return packets_; }

  double build_seconds() const { return build_seconds_; }
  size_t triangle_count() const { return indices_.size() / 3; }

 private:
  static constexpr float kInfinity = __builtin_huge_valf();

 public:
  // Embree's ray.valid() -- an assertion in Debian's build, so a process
  // abort -- needs every origin and direction component within FLT_LARGE
  // (1.844e18) and not NaN. Scene numbers are bounded (kMaxSceneMagnitude),
  // but degenerate geometry at large scales can still make NaN or huge rays;
  // they fail the render with an InputError here instead of killing the process.
  static void check_ray(const Vec3& org, const Vec3& dir) {
    constexpr double kFltLarge = 1.844e18;
    const bool valid = std::abs(org.x) <= kFltLarge && std::abs(org.y) <= kFltLarge && std::abs(org.z) <= kFltLarge &&
                       std::abs(dir.x) <= kFltLarge && std::abs(dir.y) <= kFltLarge && std::abs(dir.z) <= kFltLarge;
    if (__builtin_expect(!valid, 0)) throw_invalid_ray(org, dir);
  }
  [[noreturn]] static void throw_invalid_ray(const Vec3& org, const Vec3& dir);

 private:

  static void set_ray(RTCRay& ray, const Vec3& org, const Vec3& dir, float tnear, float tfar) {
    check_ray(org, dir);
    ray.org_x = static_cast<float>(org.x);
    ray.org_y = static_cast<float>(org.y);
    ray.org_z = static_cast<float>(org.z);
    ray.dir_x = static_cast<float>(dir.x);
    ray.dir_y = static_cast<float>(dir.y);
    ray.dir_z = static_cast<float>(dir.z);
    ray.tnear = tnear;
    ray.tfar = tfar;
    ray.mask = 0xFFFFFFFFu;
    ray.flags = 0;
    ray.time = 0;
  }

  void read_hit(float tfar, const RTCHit& h, TraceHit& hit) const {
    hit.t = tfar;
    hit.geom = h.geomID;
    hit.prim = h.primID;
    hit.u = h.u;
    hit.v = h.v;
    hit.ng = Vec3{h.Ng_x, h.Ng_y, h.Ng_z};
  }

  // Every occlusion query passes this context, and the occluded callbacks of
  // spheres and cones write into `found` what blocked a ray.
  struct OcclusionContext {
    RTCIntersectContext context;
    Occluder found;
  };
  bool occluded_single(const Vec3& org, const Vec3& dir, float tfar, Occluder* last) const;
  bool cached_blocks(const Occluder& last, const Vec3& org, const Vec3& dir) const;

  void add_triangles(const Scene& scene);
  void add_spheres(const Scene& scene, bool builtin);
  void add_cones(const Scene& scene);
  void check_error(const char* what) const;

  Vec3 origin_;
  RTCDevice device_ = nullptr;
  RTCScene scene_ = nullptr;
  RTCBuildQuality quality_ = RTC_BUILD_QUALITY_MEDIUM;
  bool packets_ = true;
  double build_seconds_ = 0;
  mutable std::string error_;  // first message from the device error callback

  std::vector<uint32_t> materials_[kKinds];  // per primitive of each kind
  // Triangle mesh, owned here and shared with Embree (vertex buffer padded so
  // the last float3 can be read with a 16-byte load).
  std::vector<float> vertex_buffer_;
  std::vector<uint32_t> indices_;
  std::vector<uint8_t> smooth_;  // per triangle: has `pp` vertex normals
  std::vector<Vec3> normals_;    // per scene vertex (`pp` only)
  // Curved primitives, camera-relative.
  struct LocalSphere {
    Vec3 center;
    double radius;
  };
  std::vector<LocalSphere> spheres_;
  std::vector<ConeShape> cones_;
  // Cones are handed to Embree as slices along their axis (tighter boxes for
  // long thin tubes at any angle); a cone hit's primID is its slice.
  struct ConeSlice {
    uint32_t cone;
    double s_lo, s_hi;  // see intersect_cone()
  };
  std::vector<ConeSlice> cone_slices_;
  std::vector<float> sphere_points_;  // built-in spheres: x y z r

  friend struct EmbreeCallbacks;
};

}  // namespace rayfarm
