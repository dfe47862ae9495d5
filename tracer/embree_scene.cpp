// EmbreeScene: device, geometry upload, user-geometry callbacks for the
// analytic spheres and cones, and the eye-ray packet path.
#include "tracer/embree_scene.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <stdexcept>

#include "tracer/error.h"
#include "tracer/triangulate.h"

namespace rayfarm {

namespace {

void on_device_error(void* user, RTCError code, const char* message) {
  auto* error = static_cast<std::string*>(user);
  if (error->empty()) error->assign("Embree error " + std::to_string(int(code)) + ": " + (message ? message : ""));
}

// Float bounds that surely contain the double-precision box [lo, hi].
RTCBounds outward_bounds(const Vec3& lo, const Vec3& hi) {
  auto down = [](double x) { return std::nextafter(static_cast<float>(x), -__builtin_huge_valf()); };
  auto up = [](double x) { return std::nextafter(static_cast<float>(x), __builtin_huge_valf()); };
  RTCBounds b;
  b.lower_x = down(lo.x);
  b.lower_y = down(lo.y);
  b.lower_z = down(lo.z);
  b.upper_x = up(hi.x);
  b.upper_y = up(hi.y);
  b.upper_z = up(hi.z);
  b.align0 = b.align1 = 0;
  return b;
}

// Shared body of the intersect/occluded callbacks: runs `solve(o, d, tnear, tfar, hit)`
// for every active ray of the (possibly packeted) call.
template <class Solve, class OnHit>
void for_each_ray(const int* valid, RTCRayN* rays, unsigned n, Solve&& solve, OnHit&& on_hit) {
  for (unsigned i = 0; i < n; ++i) {
    if (valid[i] != -1) continue;
    const Vec3 o{RTCRayN_org_x(rays, n, i), RTCRayN_org_y(rays, n, i), RTCRayN_org_z(rays, n, i)};
    const Vec3 d{RTCRayN_dir_x(rays, n, i), RTCRayN_dir_y(rays, n, i), RTCRayN_dir_z(rays, n, i)};
    ShapeHit hit;
    if (solve(o, d, RTCRayN_tnear(rays, n, i), RTCRayN_tfar(rays, n, i), hit)) on_hit(i, hit);
  }
}

}  // namespace

// User-geometry callbacks: C entry points that forward to shapes.h.
struct EmbreeCallbacks {
  template <class Solve>
  static void intersect(const RTCIntersectFunctionNArguments* args, Solve&& solve) {
    RTCRayN* rays = RTCRayHitN_RayN(args->rayhit, args->N);
    RTCHitN* hits = RTCRayHitN_HitN(args->rayhit, args->N);
    const unsigned n = args->N;
    for_each_ray(args->valid, rays, n, solve, [&](unsigned i, const ShapeHit& h) {
      RTCRayN_tfar(rays, n, i) = static_cast<float>(h.t);
      RTCHitN_Ng_x(hits, n, i) = static_cast<float>(h.normal.x);
      RTCHitN_Ng_y(hits, n, i) = static_cast<float>(h.normal.y);
      RTCHitN_Ng_z(hits, n, i) = static_cast<float>(h.normal.z);
      RTCHitN_u(hits, n, i) = 0;
      RTCHitN_v(hits, n, i) = 0;
      RTCHitN_primID(hits, n, i) = args->primID;
      RTCHitN_geomID(hits, n, i) = args->geomID;
      RTCHitN_instID(hits, n, i, 0) = args->context->instID[0];
    });
  }
  template <class Solve>
  static void occluded(const RTCOccludedFunctionNArguments* args, Solve&& solve) {
    const unsigned n = args->N;
    auto* context = reinterpret_cast<EmbreeScene::OcclusionContext*>(args->context);
    for_each_ray(args->valid, args->ray, n, solve, [&](unsigned i, const ShapeHit&) {
      RTCRayN_tfar(args->ray, n, i) = -__builtin_huge_valf();
      context->found = {args->geomID, args->primID};
    });
  }

  static auto sphere_solver(const void* user, unsigned prim) {
    const auto& s = static_cast<const EmbreeScene::LocalSphere*>(user)[prim];
    return [&s](const Vec3& o, const Vec3& d, double tn, double tf, ShapeHit& h) {
      return intersect_sphere(s.center, s.radius, o, d, tn, tf, h);
    };
  }
  static auto cone_solver(const void* user, unsigned prim) {
    const auto* es = static_cast<const EmbreeScene*>(user);
    const EmbreeScene::ConeSlice& slice = es->cone_slices_[prim];
    const ConeShape& c = es->cones_[slice.cone];
    return [&c, &slice](const Vec3& o, const Vec3& d, double tn, double tf, ShapeHit& h) {
      return intersect_cone(c, o, d, tn, tf, h, slice.s_lo, slice.s_hi);
    };
  }

  static void sphere_bounds(const RTCBoundsFunctionArguments* args) {
    const auto& s = static_cast<const EmbreeScene::LocalSphere*>(args->geometryUserPtr)[args->primID];
    const Vec3 r{s.radius, s.radius, s.radius};
    *args->bounds_o = outward_bounds(s.center - r, s.center + r);
  }
  static void sphere_intersect(const RTCIntersectFunctionNArguments* args) {
    intersect(args, sphere_solver(args->geometryUserPtr, args->primID));
  }
  static void sphere_occluded(const RTCOccludedFunctionNArguments* args) {
    occluded(args, sphere_solver(args->geometryUserPtr, args->primID));
  }

  static void cone_bounds(const RTCBoundsFunctionArguments* args) {
    const auto* es = static_cast<const EmbreeScene*>(args->geometryUserPtr);
    const EmbreeScene::ConeSlice& slice = es->cone_slices_[args->primID];
    const ConeShape& c = es->cones_[slice.cone];
    // Box around the slice's two end discs: a disc of radius r with unit normal
    // a reaches r * sqrt(1 - a_i^2) along axis i (tight for tubes at any angle).
    const double s0 = std::max(slice.s_lo, -c.half_length), s1 = std::min(slice.s_hi, c.half_length);
    const Vec3 a = c.axis;
    const Vec3 reach{std::sqrt(std::fmax(0.0, 1 - a.x * a.x)), std::sqrt(std::fmax(0.0, 1 - a.y * a.y)),
                     std::sqrt(std::fmax(0.0, 1 - a.z * a.z))};
    const double pad = 1e-9 * c.max_radius();
    const Vec3 e0 = reach * std::fabs(c.mid_radius + c.slope * s0) + Vec3{pad, pad, pad};
    const Vec3 e1 = reach * std::fabs(c.mid_radius + c.slope * s1) + Vec3{pad, pad, pad};
    const Vec3 p0 = c.center + s0 * a, p1 = c.center + s1 * a;
    const Vec3 b0 = p0 - e0, b1 = p1 - e1, c0 = p0 + e0, c1 = p1 + e1;
    const Vec3 lo{std::min(b0.x, b1.x), std::min(b0.y, b1.y), std::min(b0.z, b1.z)};
    const Vec3 hi{std::max(c0.x, c1.x), std::max(c0.y, c1.y), std::max(c0.z, c1.z)};
    *args->bounds_o = outward_bounds(lo, hi);
  }
  static void cone_intersect(const RTCIntersectFunctionNArguments* args) {
    intersect(args, cone_solver(args->geometryUserPtr, args->primID));
  }
  static void cone_occluded(const RTCOccludedFunctionNArguments* args) {
    occluded(args, cone_solver(args->geometryUserPtr, args->primID));
  }
};

EmbreeScene::EmbreeScene(const Scene& scene, const EmbreeOptions& options) : origin_(scene.camera.from) {
  const auto start = std::chrono::steady_clock::now();
  device_ = rtcNewDevice(nullptr);
  if (!device_) throw std::runtime_error("Embree: cannot create device (error " +
                                         std::to_string(int(rtcGetDeviceError(nullptr))) + ")");
  rtcSetDeviceErrorFunction(device_, on_device_error, &error_);
  scene_ = rtcNewScene(device_);
  rtcSetSceneFlags(scene_, options.robust_bvh ? RTC_SCENE_FLAG_ROBUST : RTC_SCENE_FLAG_NONE);
  quality_ = options.high_quality ? RTC_BUILD_QUALITY_HIGH : RTC_BUILD_QUALITY_MEDIUM;
  rtcSetSceneBuildQuality(scene_, quality_);
  add_triangles(scene);
  add_spheres(scene, options.builtin_spheres);
  add_cones(scene);
  // Packets pay off when most primitives are triangles or spheres, not when
  // cones are a large share: Embree's packet traversal then runs the cone
  // callback about twice as often per ray as single-ray traversal does (its
  // leaves hold slices of long thin tubes that few rays of a packet hit).
  // Measured at 256x256, 16 spp, one core, 2-3 runs each: rings-7 (half its
  // primitives cones) 1.72 s single vs 1.97 s packets (at 512x512, with the
  // shadow cache below: 6.0 vs 6.9 s); triangle and sphere scenes the other
  // way round (mount-6 0.77 vs 0.38 s, balls-4 0.81 vs 0.72 s).
  packets_ = 4 * scene.cones.size() < scene.primitive_count();
  rtcCommitScene(scene_);
  check_error("building the scene");
  build_seconds_ = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
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

void attach(RTCScene scene, RTCGeometry geometry, uint32_t id, RTCBuildQuality quality) {
  rtcSetGeometryBuildQuality(geometry, quality);
  rtcCommitGeometry(geometry);
  rtcAttachGeometryByID(scene, geometry, id);
  rtcReleaseGeometry(geometry);
}
}  // namespace

void EmbreeScene::add_triangles(const Scene& scene) {
  if (scene.polygons.empty()) return;
  vertex_buffer_.resize(3 * scene.vertices.size() + 1, 0.0f);  // +1: 16-byte readable tail
  for (size_t i = 0; i < scene.vertices.size(); ++i) {
    const Vec3 p = to_local(scene.vertices[i]);
    vertex_buffer_[3 * i + 0] = static_cast<float>(p.x);
    vertex_buffer_[3 * i + 1] = static_cast<float>(p.y);
    vertex_buffer_[3 * i + 2] = static_cast<float>(p.z);
  }
  const bool any_smooth = !scene.normals.empty();
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
      materials_[kTriangles].push_back(material_of(scene, poly.material));
      if (any_smooth) smooth_.push_back(poly.has_normals ? 1 : 0);
    }
  }
  if (any_smooth) normals_ = scene.normals;
  if (indices_.empty()) return;
  RTCGeometry geometry = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_TRIANGLE);
  rtcSetSharedGeometryBuffer(geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, vertex_buffer_.data(), 0,
                             3 * sizeof(float), scene.vertices.size());
  rtcSetSharedGeometryBuffer(geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, indices_.data(), 0,
                             3 * sizeof(uint32_t), indices_.size() / 3);
  attach(scene_, geometry, kTriangles, quality_);
  check_error("triangles");
}

void EmbreeScene::add_spheres(const Scene& scene, bool builtin) {
  if (scene.spheres.empty()) return;
  for (const Sphere& s : scene.spheres) {
    spheres_.push_back({to_local(s.center), std::fabs(s.radius)});
    materials_[kSpheres].push_back(material_of(scene, s.material));
  }
  RTCGeometry geometry;
  if (builtin) {
    geometry = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_SPHERE_POINT);
    for (const LocalSphere& s : spheres_) {
      sphere_points_.insert(sphere_points_.end(),
                            {float(s.center.x), float(s.center.y), float(s.center.z), float(s.radius)});
    }
    rtcSetSharedGeometryBuffer(geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT4, sphere_points_.data(), 0,
                               4 * sizeof(float), spheres_.size());
  } else {
    geometry = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_USER);
    rtcSetGeometryUserPrimitiveCount(geometry, static_cast<unsigned>(spheres_.size()));
    rtcSetGeometryUserData(geometry, spheres_.data());
    rtcSetGeometryBoundsFunction(geometry, EmbreeCallbacks::sphere_bounds, nullptr);
    rtcSetGeometryIntersectFunction(geometry, EmbreeCallbacks::sphere_intersect);
    rtcSetGeometryOccludedFunction(geometry, EmbreeCallbacks::sphere_occluded);
  }
  attach(scene_, geometry, kSpheres, quality_);
  check_error("spheres");
}

void EmbreeScene::add_cones(const Scene& scene) {
  // User geometry over intersect_cone(). (Embree's RTC_GEOMETRY_TYPE_CONE_LINEAR_CURVE
  // with both neighbour flags set, the way to suppress its end caps, clips each
  // segment against its neighbours' vertices; NFF cones are independent segments,
  // and rings-7 rendered that way came out wrong, +10% reflection rays.)
  if (scene.cones.empty()) return;
  for (const Cone& c : scene.cones) {
    const ConeShape shape = ConeShape::make(to_local(c.base), c.base_radius, to_local(c.apex), c.apex_radius);
    const auto cone = static_cast<uint32_t>(cones_.size());
    cones_.push_back(shape);
    // Slices about four radii long, at most kMaxSlices; the first and last are
    // open-ended so the cone's own end test applies there.
    constexpr int kMaxSlices = 8;
    const double len = 2 * shape.half_length, r = std::max(shape.max_radius(), 1e-300);
    const int n = std::clamp(static_cast<int>(std::ceil(len / (4 * r))), 1, kMaxSlices);
    for (int i = 0; i < n; ++i) {
      const double lo = i == 0 ? -HUGE_VAL : -shape.half_length + len * i / n;
      const double hi = i == n - 1 ? HUGE_VAL : -shape.half_length + len * (i + 1) / n;
      cone_slices_.push_back({cone, lo, hi});
      materials_[kCones].push_back(material_of(scene, c.material));
    }
  }
  RTCGeometry geometry = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_USER);
  rtcSetGeometryUserPrimitiveCount(geometry, static_cast<unsigned>(cone_slices_.size()));
  rtcSetGeometryUserData(geometry, this);
  rtcSetGeometryBoundsFunction(geometry, EmbreeCallbacks::cone_bounds, nullptr);
  rtcSetGeometryIntersectFunction(geometry, EmbreeCallbacks::cone_intersect);
  rtcSetGeometryOccludedFunction(geometry, EmbreeCallbacks::cone_occluded);
  attach(scene_, geometry, kCones, quality_);
  check_error("cones");
}

namespace {
// Fills lane i of a 16-wide packet; lanes >= count are disabled.
void set_lane(RTCRay16& r, int i, const Vec3& org, const Vec3& dir, float tfar) {
  EmbreeScene::check_ray(org, dir);
  r.org_x[i] = static_cast<float>(org.x);
  r.org_y[i] = static_cast<float>(org.y);
  r.org_z[i] = static_cast<float>(org.z);
  r.dir_x[i] = static_cast<float>(dir.x);
  r.dir_y[i] = static_cast<float>(dir.y);
  r.dir_z[i] = static_cast<float>(dir.z);
  r.tnear[i] = 0.0f;
  r.tfar[i] = tfar;
  r.mask[i] = 0xFFFFFFFFu;
  r.flags[i] = 0;
  r.time[i] = 0;
}
}  // namespace

void EmbreeScene::intersect_packet(const Vec3* orgs, const Vec3* dirs, int count, TraceHit* hits) const {
  if (count == 1 || !packets_) {
    for (int i = 0; i < count; ++i) {
      if (!intersect(orgs[i], dirs[i], hits[i])) hits[i].geom = RTC_INVALID_GEOMETRY_ID;
    }
    return;
  }
  alignas(64) RTCRayHit16 packet;
  alignas(64) int valid[kPacket];
  for (int i = 0; i < kPacket; ++i) {
    valid[i] = i < count ? -1 : 0;
    const int src = i < count ? i : 0;
    set_lane(packet.ray, i, orgs[src], dirs[src], kInfinity);
    packet.hit.geomID[i] = RTC_INVALID_GEOMETRY_ID;
    packet.hit.instID[0][i] = RTC_INVALID_GEOMETRY_ID;
  }
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  context.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
  rtcIntersect16(valid, scene_, &context, &packet);
  for (int i = 0; i < count; ++i) {
    hits[i].geom = packet.hit.geomID[i];
    if (hits[i].geom == RTC_INVALID_GEOMETRY_ID) continue;
    hits[i].t = packet.ray.tfar[i];
    hits[i].prim = packet.hit.primID[i];
    hits[i].u = packet.hit.u[i];
    hits[i].v = packet.hit.v[i];
    hits[i].ng = Vec3{packet.hit.Ng_x[i], packet.hit.Ng_y[i], packet.hit.Ng_z[i]};
  }
}

// Whether the remembered sphere or cone blocks org + t*dir, t in (0, 1): the
// ray as Embree would see it (rounded to float) through the same solver.
bool EmbreeScene::cached_blocks(const Occluder& last, const Vec3& org, const Vec3& dir) const {
  const Vec3 o{float(org.x), float(org.y), float(org.z)}, d{float(dir.x), float(dir.y), float(dir.z)};
  ShapeHit hit;
  if (last.geom == kSpheres) return EmbreeCallbacks::sphere_solver(spheres_.data(), last.prim)(o, d, 0.0, 1.0, hit);
  if (last.geom == kCones) return EmbreeCallbacks::cone_solver(this, last.prim)(o, d, 0.0, 1.0, hit);
  return false;
}

bool EmbreeScene::occluded_single(const Vec3& org, const Vec3& dir, float tfar, Occluder* last) const {
  if (last && tfar == 1.0f && cached_blocks(*last, org, dir)) return true;
  OcclusionContext context;
  rtcInitIntersectContext(&context.context);
  RTCRay ray;
  set_ray(ray, org, dir, 0.0f, tfar);
  rtcOccluded1(scene_, &context.context, &ray);
  if (ray.tfar >= 0) return false;
  if (last) *last = context.found;  // still "none" when a triangle blocked the ray
  return true;
}

void EmbreeScene::occluded_packet(const Vec3* orgs, const Vec3* dirs, int count, bool* blocked,
                                  Occluder* last) const {
  // The shadow cache serves single rays only: in packet scenes (mostly
  // triangles, or spheres) checking it per lane cost 4-5% on balls-4 and gears-4.
  if (count == 1 || !packets_) {
    for (int i = 0; i < count; ++i) blocked[i] = occluded_single(orgs[i], dirs[i], 1.0f, last);
    return;
  }
  alignas(64) RTCRay16 packet;
  alignas(64) int valid[kPacket];
  for (int i = 0; i < kPacket; ++i) {
    valid[i] = i < count ? -1 : 0;
    const int src = i < count ? i : 0;
    set_lane(packet, i, orgs[src], dirs[src], 1.0f);
  }
  OcclusionContext context;
  rtcInitIntersectContext(&context.context);
  context.context.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
  rtcOccluded16(valid, scene_, &context.context, &packet);
  for (int i = 0; i < count; ++i) blocked[i] = packet.tfar[i] < 0;
}

}  // namespace rayfarm
