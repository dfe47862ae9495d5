// Geometry: the analytic sphere and cone solvers (shapes.h), the Embree scene
// built from them and from ear-clipped concave polygons, and the Wachter-Binder
// ray offset (no spawned ray re-hits the surface it leaves).
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <random>

#include "tracer/embree_scene.h"
#include "tracer/ray_offset.h"
#include "tracer/shapes.h"

using namespace rayfarm;

namespace {
constexpr double kInf = 1e300;

Vec3 unit(const Vec3& v) { return v / length(v); }

// A gear outline like the SPD gears' faces: 4 points per tooth, tips at `outer`,
// roots at 0.9 * outer, counter-clockwise seen from +z.
std::vector<Vec3> gear_outline(int teeth, double outer, double z) {
  const double kPi = 3.14159265358979323846, tau = 2 * kPi / teeth;
  std::vector<Vec3> v;
  for (int k = 0; k < teeth; ++k) {
    const double a = k * tau;
    for (auto [f, r] : {std::pair{-0.19, outer}, {0.19, outer}, {0.3, 0.9 * outer}, {0.7, 0.9 * outer}}) {
      v.push_back({r * std::cos(a + f * tau), r * std::sin(a + f * tau), z});
    }
  }
  return v;
}

Scene scene_looking_down(const Vec3& offset = {}) {
  Scene s;
  s.camera.from = Vec3{0, 0, 10} + offset;
  s.camera.at = offset;
  s.camera.up = {0, 1, 0};
  s.materials.push_back(Material{});
  return s;
}

void add_polygon(Scene& s, const std::vector<Vec3>& verts, const Vec3& offset = {}) {
  Polygon p;
  p.first = static_cast<uint32_t>(s.vertices.size());
  p.count = static_cast<uint32_t>(verts.size());
  for (const Vec3& v : verts) s.vertices.push_back(v + offset);
  s.polygons.push_back(p);
}

// Shoots straight down (-z) from height 10 above world point (x, y).
bool hits_down(const EmbreeScene& es, double x, double y, const Vec3& offset, TraceHit* out = nullptr) {
  TraceHit hit;
  const bool h = es.intersect(es.to_local(Vec3{x, y, 10} + offset), {0, 0, -1}, hit);
  if (out) *out = hit;
  return h;
}

// Whether org + t dir hits anything alone; checks that `packed`, the same
// ray's hit from a packet, is the same to the bit.
bool same_as_alone(const EmbreeScene& es, const Vec3& org, const Vec3& dir, const TraceHit& packed,
                   const Departure& departure = {}) {
  TraceHit alone;
  const bool hit = es.intersect(org, dir, alone, departure);
  REQUIRE(hit == (packed.geom != RTC_INVALID_GEOMETRY_ID));
  if (!hit) return false;
  CHECK(alone.geom == packed.geom);
  CHECK(alone.prim == packed.prim);
  CHECK(std::memcmp(&alone.t, &packed.t, sizeof(double)) == 0);
  CHECK(std::memcmp(&alone.ng, &packed.ng, sizeof(Vec3)) == 0);
  CHECK(std::memcmp(&alone.u, &packed.u, sizeof(double)) == 0);
  return true;
}
}  // namespace

TEST_CASE("geometry: ray/sphere hits, misses, inside and grazing") {
  const Vec3 c{0, 0, 0};
  ShapeHit h;
  REQUIRE(intersect_sphere(c, 1, {0, 0, -5}, {0, 0, 1}, 0, kInf, h));
  CHECK(h.t == doctest::Approx(4));
  CHECK(unit(h.normal).z == doctest::Approx(-1));
  // Unnormalised direction: t scales inversely.
  REQUIRE(intersect_sphere(c, 1, {0, 0, -5}, {0, 0, 2}, 0, kInf, h));
  CHECK(h.t == doctest::Approx(2));
  CHECK_FALSE(intersect_sphere(c, 1, {1.5, 0, -5}, {0, 0, 1}, 0, kInf, h));
  CHECK_FALSE(intersect_sphere(c, 1, {0, 0, 5}, {0, 0, 1}, 0, kInf, h));  // sphere behind
  // From inside: the far wall, with the outward normal.
  REQUIRE(intersect_sphere(c, 1, {0, 0, 0}, {0, 0, 1}, 0, kInf, h));
  CHECK(h.t == doctest::Approx(1));
  CHECK(unit(h.normal).z == doctest::Approx(1));
  // Grazing: tangent ray touches once, a hair further out misses.
  REQUIRE(intersect_sphere(c, 1, {1, 0, -5}, {0, 0, 1}, 0, kInf, h));
  CHECK(h.t == doctest::Approx(5));
  CHECK_FALSE(intersect_sphere(c, 1, {1 + 1e-9, 0, -5}, {0, 0, 1}, 0, kInf, h));
  // tfar limits the search (occlusion queries use it).
  CHECK_FALSE(intersect_sphere(c, 1, {0, 0, -5}, {0, 0, 1}, 0, 3.9, h));
  // Small sphere far away (Ray Tracing Gems ch. 7): still found, at the right t.
  REQUIRE(intersect_sphere({0, 1e4, 1e6}, 1e-3, {0, 0, 0}, unit({0, 1e4, 1e6}), 0, kInf, h));
  CHECK(h.t == doctest::Approx(length(Vec3{0, 1e4, 1e6}) - 1e-3).epsilon(1e-12));
}

TEST_CASE("geometry: ray/cone and cylinder, open ends, inside and parallel rays") {
  ShapeHit h;
  const ConeShape cyl = ConeShape::make({0, 0, 0}, 1, {0, 0, 2}, 1);
  REQUIRE(intersect_cone(cyl, {-5, 0, 1}, {1, 0, 0}, 0, kInf, h));
  CHECK(h.t == doctest::Approx(4));
  CHECK(unit(h.normal).x == doctest::Approx(-1));
  CHECK_FALSE(intersect_cone(cyl, {-5, 0, 3}, {1, 0, 0}, 0, kInf, h));   // above the top
  CHECK_FALSE(intersect_cone(cyl, {-5, 0, -1}, {1, 0, 0}, 0, kInf, h));  // below the base
  // From inside: far wall, outward normal.
  REQUIRE(intersect_cone(cyl, {0, 0, 1}, {1, 0, 0}, 0, kInf, h));
  CHECK(h.t == doctest::Approx(1));
  CHECK(unit(h.normal).x == doctest::Approx(1));
  // Parallel to the axis: through the open ends, inside or outside.
  CHECK_FALSE(intersect_cone(cyl, {0.5, 0, -1}, {0, 0, 1}, 0, kInf, h));
  CHECK_FALSE(intersect_cone(cyl, {2, 0, -1}, {0, 0, 1}, 0, kInf, h));
  // In through the open bottom, out through the wall from inside.
  REQUIRE(intersect_cone(cyl, {0, 0, -1}, {0.5, 0, 1}, 0, kInf, h));
  CHECK(h.t == doctest::Approx(2));
  // Grazing the side.
  REQUIRE(intersect_cone(cyl, {1, -5, 1}, {0, 1, 0}, 0, kInf, h));
  CHECK(h.t == doctest::Approx(5));
  CHECK_FALSE(intersect_cone(cyl, {1 + 1e-9, -5, 1}, {0, 1, 0}, 0, kInf, h));

  // A true cone, radius 1 at z = 0 to 0 at z = 1.
  const ConeShape cone = ConeShape::make({0, 0, 0}, 1, {0, 0, 1}, 0);
  REQUIRE(intersect_cone(cone, {-5, 0, 0.5}, {1, 0, 0}, 0, kInf, h));
  CHECK(h.t == doctest::Approx(4.5));
  CHECK(unit(h.normal).x == doctest::Approx(-std::sqrt(0.5)));
  CHECK(unit(h.normal).z == doctest::Approx(std::sqrt(0.5)));
  // The mirrored nappe above the apex is not part of the cone.
  CHECK_FALSE(intersect_cone(cone, {-5, 0, 1.5}, {1, 0, 0}, 0, kInf, h));
  // Ray parallel to a generating line (the quadratic degenerates to linear).
  REQUIRE(intersect_cone(cone, {-2, 0, 2}, {1, 0, -1}, 0, kInf, h));
  CHECK(h.t == doctest::Approx(1.5));
  // Reversed cone description (apex radius larger) is the same surface.
  const ConeShape flipped = ConeShape::make({0, 0, 1}, 0, {0, 0, 0}, 1);
  REQUIRE(intersect_cone(flipped, {-5, 0, 0.5}, {1, 0, 0}, 0, kInf, h));
  CHECK(h.t == doctest::Approx(4.5));
}

TEST_CASE("geometry: concave gear polygon through the Embree scene, hits and notch misses") {
  for (const Vec3 offset : {Vec3{0, 0, 0}, Vec3{1e6, -1e6, 1e6}}) {
    CAPTURE(offset.x);
    Scene s = scene_looking_down(offset);
    add_polygon(s, gear_outline(36, 1.0, 0.0), offset);
    // A U-shaped polygon: the notch x in (1, 2), y in (1, 2) is outside it.
    add_polygon(s, {{3, 0, 0}, {6, 0, 0}, {6, 2, 0}, {5, 2, 0}, {5, 1, 0}, {4, 1, 0}, {4, 2, 0}, {3, 2, 0}}, offset);
    const EmbreeScene es(s, EmbreeOptions{});
    const double kPi = 3.14159265358979323846, tau = 2 * kPi / 36;
    int tooth_hits = 0, notch_hits = 0;
    for (int k = 0; k < 36; ++k) {
      const double tooth = k * tau, gap = (k + 0.5) * tau, r = 0.95;
      tooth_hits += hits_down(es, r * std::cos(tooth), r * std::sin(tooth), offset);
      notch_hits += hits_down(es, r * std::cos(gap), r * std::sin(gap), offset);
    }
    CHECK(tooth_hits == 36);
    CHECK(notch_hits == 0);  // a triangle fan would fill these gaps
    TraceHit hit;
    REQUIRE(hits_down(es, 0.1, 0.2, offset, &hit));
    CHECK(hit.t == doctest::Approx(10));
    CHECK(unit(hit.ng).z == doctest::Approx(1));  // counter-clockwise from +z faces +z
    CHECK(hits_down(es, 3.5, 1.5, offset));
    CHECK(hits_down(es, 4.5, 0.5, offset));
    CHECK_FALSE(hits_down(es, 4.5, 1.5, offset));
    CHECK_FALSE(hits_down(es, 6.5, 1.0, offset));
  }
}

TEST_CASE("geometry: spheres and cones through the Embree scene") {
  for (const Vec3 offset : {Vec3{0, 0, 0}, Vec3{-1e6, 1e6, 1e6}}) {
    Scene s = scene_looking_down(offset);
    s.spheres.push_back({Vec3{0, 0, 0} + offset, 1.0, 0});
    s.cones.push_back({Vec3{3, 0, -1} + offset, 0.5, Vec3{3, 0, 1} + offset, 0.5, 0});
    const EmbreeScene es(s, EmbreeOptions{});
    TraceHit hit;
    REQUIRE(hits_down(es, 0, 0, offset, &hit));
    CHECK(hit.geom == EmbreeScene::kSpheres);
    CHECK(hit.t == doctest::Approx(9).epsilon(1e-5));
    CHECK(unit(hit.ng).z == doctest::Approx(1).epsilon(1e-4));
    CHECK_FALSE(hits_down(es, 1.01, 0, offset));
    // Down the axis of the open cylinder: nothing to hit.
    CHECK_FALSE(hits_down(es, 3, 0, offset));
    // Sideways into the cylinder wall.
    REQUIRE(es.intersect(es.to_local(Vec3{5, 0, 0} + offset), {-1, 0, 0}, hit));
    CHECK(hit.geom == EmbreeScene::kCones);
    CHECK(hit.t == doctest::Approx(1.5).epsilon(1e-5));
    CHECK(unit(hit.ng).x == doctest::Approx(1).epsilon(1e-4));
    // From inside the cylinder: the far wall, normal still outward.
    REQUIRE(es.intersect(es.to_local(Vec3{3, 0, 0} + offset), {1, 0, 0}, hit));
    CHECK(hit.t == doctest::Approx(0.5).epsilon(1e-5));
    CHECK(unit(hit.ng).x == doctest::Approx(1).epsilon(1e-4));
    CHECK(es.occluded(es.to_local(Vec3{5, 0, 0} + offset), {-4, 0, 0}, 1.0f));
    CHECK_FALSE(es.occluded(es.to_local(Vec3{5, 0, 0} + offset), {0, 4, 0}, 1.0f));
  }
}
TEST_CASE("geometry: a quad's two halves, tested as one piece, both hit, and its diagonal goes to the lower") {
  // Embree sees a quad as one piece that tests both its triangles: a ray
  // anywhere on it hits, alone or in a packet, with the same triangle; on
  // the diagonal both triangles meet the ray at the same t, and the tie rule
  // gives the hit to the quad's first triangle (an even index, 2q). The
  // squares lie at integers and the rays go straight down, so the
  // arithmetic is exact and the diagonal's rays lie exactly on it.
  Scene s = scene_looking_down();
  for (int q = 0; q < 4; ++q) add_polygon(s, {{2.0 * q, 0, 0}, {2.0 * q + 1, 0, 0}, {2.0 * q + 1, 1, 0}, {2.0 * q, 1, 0}});
  const EmbreeScene es(s, EmbreeOptions{});
  REQUIRE(es.triangle_count() == 8);
  for (int q = 0; q < 4; ++q) {
    CAPTURE(q);
    const double x0 = 2.0 * q;
    // 16 rays along each diagonal, then 16 off both, as packets and alone.
    Vec3 orgs[3][EmbreeScene::kPacket], dirs[EmbreeScene::kPacket], to_floor[EmbreeScene::kPacket];
    for (int k = 0; k < EmbreeScene::kPacket; ++k) {
      const double f = (k + 0.5) / EmbreeScene::kPacket;
      orgs[0][k] = es.to_local({x0 + f, f, 10});
      orgs[1][k] = es.to_local({x0 + f, 1 - f, 10});
      orgs[2][k] = es.to_local({x0 + f, k % 2 ? 0.1 : 0.9, 10});
      dirs[k] = {0, 0, -1};
      to_floor[k] = {0, 0, -20};  // a shadow ray's t in (0, 1) reaches z = -10
    }
    int lower_on[2] = {0, 0};
    uint32_t seen = 0;  // bit 0: the first triangle was hit, bit 1: the second
    for (int line = 0; line < 3; ++line) {
      TraceHit packed[EmbreeScene::kPacket];
      es.intersect_packet(orgs[line], dirs, EmbreeScene::kPacket, packed);
      bool blocked[EmbreeScene::kPacket];
      es.occluded_packet(orgs[line], to_floor, EmbreeScene::kPacket, blocked);
      for (int k = 0; k < EmbreeScene::kPacket; ++k) {
        TraceHit alone;
        REQUIRE(es.intersect(orgs[line][k], dirs[k], alone));
        REQUIRE(packed[k].geom == EmbreeScene::kTriangles);
        CHECK(alone.prim == packed[k].prim);
        CHECK(alone.t == 10);
        CHECK(packed[k].t == 10);
        CHECK(blocked[k]);
        CHECK(es.occluded(orgs[line][k], to_floor[k], 1.0));
        REQUIRE((alone.prim == 2u * q || alone.prim == 2u * q + 1));
        seen |= 1u << (alone.prim - 2 * q);
        if (line < 2) lower_on[line] += alone.prim == 2u * q;
      }
    }
    CHECK(seen == 3);
    // One diagonal is the shared edge: all 16 rays on it go to the first
    // triangle; the other crosses both halves.
    CHECK(std::max(lower_on[0], lower_on[1]) == EmbreeScene::kPacket);
    CHECK(std::min(lower_on[0], lower_on[1]) < EmbreeScene::kPacket);
  }
}


TEST_CASE("geometry: rays spawned with the Wachter-Binder offset never re-hit their surface") {
  // pbrt's Triangle.Reintersect idea: hit, offset the origin to the outgoing side
  // along the geometric normal, trace in a random direction on that side.
  for (const Vec3 offset : {Vec3{0, 0, 0}, Vec3{3e5, -2e5, 1e5}}) {
    Scene s = scene_looking_down(offset);
    s.camera.from = Vec3{2, 3, 4} + offset;
    s.spheres.push_back({Vec3{0, 0, 0} + offset, 0.5, 0});
    s.cones.push_back({Vec3{0, 2, -1} + offset, 0.3, Vec3{0, 2, 1} + offset, 0.1, 0});
    add_polygon(s, {{-10, -10, -2}, {10, -10, -2}, {10, 10, -2}, {-10, 10, -2}}, offset);
    const EmbreeScene es(s, EmbreeOptions{});
    std::mt19937_64 rng(1234);
    std::uniform_real_distribution<double> u(-1, 1);
    int spawned = 0, rehits = 0;
    for (int i = 0; i < 20000; ++i) {
      const Vec3 dir{u(rng), u(rng), u(rng)};
      TraceHit hit;
      if (!es.intersect({0, 0, 0}, dir, hit)) continue;
      const Vec3 p = hit.t * dir;
      Vec3 n = unit(hit.ng);
      if (dot(n, dir) > 0) n = -n;  // towards the side the ray came from
      Vec3 out{u(rng), u(rng), u(rng)};
      if (dot(out, n) < 0) out = -out;
      if (std::fabs(dot(unit(out), n)) < 1e-3) continue;
      ++spawned;
      TraceHit again;
      const Vec3 from = offset_ray_origin(p, n, offset_scale(p, Vec3{}));
      if (es.intersect(from, out, again) && again.geom == hit.geom && again.prim == hit.prim && again.t < 1e-3) {
        ++rehits;
      }
    }
    CHECK(spawned > 1000);
    CHECK(rehits == 0);
  }
}

TEST_CASE("geometry: a ray hits the same, to the bit, traced alone or in a packet") {
  // Every exact test runs on the float-rounded ray Embree holds, whichever path
  // the ray takes: single-ray traversal, or a packet through the lane kernels
  // (triangles, spheres, cones) and the ray-by-ray fallback, so the two paths
  // agree to the bit. (It fails
  // when a packet's lane kernels get the unrounded rays; it did not catch the
  // GCC 12 rounding bug, which struck both paths alike here: the test below
  // does.)
  Scene s = scene_looking_down();
  s.camera.from = {0.3, -7.1, 2.9};
  std::mt19937_64 rng(77);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int i = 0; i < 300; ++i) {
    const Vec3 c{3 * u(rng), 3 * u(rng), 3 * u(rng)};
    add_polygon(s, {c + Vec3{0, 0, 0}, c + Vec3{0.4 * u(rng), 0.5, 0.1}, c + Vec3{0.5, 0.3 * u(rng), 0.2}});
    s.spheres.push_back({c + Vec3{u(rng), u(rng), u(rng)}, 0.05 + 0.2 * std::fabs(u(rng)), 0});
    if (i % 2) continue;  // tubes and cones, some long enough to be sliced
    const Vec3 base = c + Vec3{u(rng), u(rng), u(rng)}, apex = base + 1.5 * Vec3{u(rng), u(rng), u(rng)};
    const double radius = 0.03 + 0.1 * std::fabs(u(rng));
    s.cones.push_back({base, radius, apex, i % 4 ? radius : 0.5 * radius, 0});
  }
  // Embree hands the callbacks a 16-ray packet whole only where it walks 16
  // rays at once (AVX-512); below that, in windows of 8 or 4 of its lanes,
  // which the lane kernels must take as the packet's own lanes.
  EmbreeOptions options;
  SUBCASE("at this CPU's widest kernels") {}
  SUBCASE("capped at AVX2: Embree's windows of 8 lanes") { options.max_isa = "avx2"; }
  SUBCASE("capped at SSE4.2: Embree's windows of 4 lanes") { options.max_isa = "sse4.2"; }
  const EmbreeScene es(s, options);
  const Vec3 eye = es.to_local(s.camera.from);
  int hits = 0, blocked = 0, cache_moved = 0, apart_blocked = 0, apart_hit = 0;
  EmbreeScene::ShadowCache cache, start_caches[3];
  for (int p = 0; p < 200; ++p) {
    // One pixel's 16 coherent samples, as the renderer sends them.
    const Vec3 aim = unit(Vec3{0, 7, -2.9} + 0.8 * Vec3{u(rng), 0, u(rng)});
    Vec3 orgs[EmbreeScene::kPacket], dirs[EmbreeScene::kPacket];
    for (int k = 0; k < EmbreeScene::kPacket; ++k) {
      orgs[k] = eye + Vec3{1e-3 * u(rng), 1e-3 * u(rng), 1e-3 * u(rng)};
      dirs[k] = aim + 0.002 * Vec3{u(rng), u(rng), u(rng)};
    }
    TraceHit packed[EmbreeScene::kPacket];
    es.intersect_packet(orgs, dirs, EmbreeScene::kPacket, packed);
    Vec3 from[EmbreeScene::kPacket], to_light[EmbreeScene::kPacket];
    // Shadow rays from below the geometry through it, towards a light above.
    const Vec3 spot{2.5 * u(rng), 2.5 * u(rng), -4};
    for (int k = 0; k < EmbreeScene::kPacket; ++k) {
      from[k] = es.to_local(spot + 0.01 * Vec3{u(rng), u(rng), u(rng)});
      to_light[k] = es.to_local(Vec3{0, 0, 6}) - from[k];
    }
    bool shadowed[EmbreeScene::kPacket], via_cache[EmbreeScene::kPacket];
    es.occluded_packet(from, to_light, EmbreeScene::kPacket, shadowed);
    // The light's shadow cache, kept across packets, answers some lanes
    // before the BVH does, and must answer them alike.
    const EmbreeScene::ShadowCache before = cache;
    es.occluded_packet(from, to_light, EmbreeScene::kPacket, via_cache, &cache);
    CHECK(std::equal(shadowed, shadowed + EmbreeScene::kPacket, via_cache));
    cache_moved += !(before.first == cache.first);
    // Shadow rays from points far apart, as mirror rays' hits can be: ray by
    // ray through the single-ray walk (occluded_packet()), with the same
    // answers; from the close points above, the packet's walk.
    Vec3 apart[EmbreeScene::kPacket], apart_to_light[EmbreeScene::kPacket];
    for (int k = 0; k < EmbreeScene::kPacket; ++k) {
      apart[k] = es.to_local(Vec3{2.5 * u(rng), 2.5 * u(rng), -4 + u(rng)});
      apart_to_light[k] = es.to_local(Vec3{0, 0, 6}) - apart[k];
    }
    bool apart_shadowed[EmbreeScene::kPacket], apart_via_cache[EmbreeScene::kPacket], close[EmbreeScene::kPacket];
    const auto scattered = EmbreeScene::Origins::kScattered;
    es.occluded_packet(apart, apart_to_light, EmbreeScene::kPacket, apart_shadowed, nullptr, scattered);
    es.occluded_packet(apart, apart_to_light, EmbreeScene::kPacket, apart_via_cache, &cache, scattered);
    es.occluded_packet(from, to_light, EmbreeScene::kPacket, close, &cache, scattered);
    CHECK(std::equal(shadowed, shadowed + EmbreeScene::kPacket, close));
    // Each ray with a cache of its own, as the renderer gives the rays it
    // walks one by one (StartShadowCaches): here rays 0, 3, 6, ... share one,
    // 1, 4, 7, ... another, kept across packets.
    EmbreeScene::ShadowCache* caches[EmbreeScene::kPacket];
    for (int k = 0; k < EmbreeScene::kPacket; ++k) caches[k] = &start_caches[k % 3];
    bool apart_via_own[EmbreeScene::kPacket];
    es.occluded_alone(apart, apart_to_light, EmbreeScene::kPacket, apart_via_own, caches);
    for (int k = 0; k < EmbreeScene::kPacket; ++k) {
      CHECK(es.occluded(apart[k], apart_to_light[k], 1.0) == apart_shadowed[k]);
      CHECK(apart_via_cache[k] == apart_shadowed[k]);
      CHECK(apart_via_own[k] == apart_shadowed[k]);
      apart_blocked += apart_shadowed[k];
    }
    // Mirror rays, as from those points far apart (ray by ray through the
    // single-ray walk, intersect_packet()) and from the eye's close ones
    // (Embree's packet walk): the same hits as alone.
    Vec3 bounced[EmbreeScene::kPacket];
    for (Vec3& d : bounced) d = {u(rng), u(rng), u(rng)};
    TraceHit apart_hits[EmbreeScene::kPacket], close_hits[EmbreeScene::kPacket];
    es.intersect_packet(apart, bounced, EmbreeScene::kPacket, apart_hits, scattered);
    es.intersect_packet(orgs, dirs, EmbreeScene::kPacket, close_hits, scattered);
    for (int k = 0; k < EmbreeScene::kPacket; ++k) {
      hits += same_as_alone(es, orgs[k], dirs[k], packed[k]);
      apart_hit += same_as_alone(es, apart[k], bounced[k], apart_hits[k]);
      same_as_alone(es, orgs[k], dirs[k], close_hits[k]);
      CHECK(es.occluded(from[k], to_light[k], 1.0) == shadowed[k]);
      blocked += shadowed[k];
    }
  }
  CHECK(hits > 500);
  CHECK(apart_hit > 500);
  CHECK(blocked > 100);
  CHECK(apart_blocked > 100);
  CHECK(cache_moved > 10);
  for (const auto& own : start_caches) CHECK(own.first.geom != RTC_INVALID_GEOMETRY_ID);  // they were used
}

TEST_CASE("geometry: the exact tests see the float ray Embree holds, alone and in a packet") {
  // Rays whose slope in one component, rounded to float, passes a triangle's
  // edge on the other side than the double slope does: the exact test must
  // decide on the rounded ray, as Embree walks it, whichever path the ray
  // takes. Each component in turn: GCC 12's vectorizer dropped the rounding
  // of some components only (before the fix, axis 1 failed, alone and in
  // packets).
  const double slope = 0.1 + 1e-12;                          // float(slope) = 0.10000000149...
  const double edge = 0.5 * (slope + double(float(slope)));  // between the two at distance 1
  volatile float rounded = static_cast<float>(slope);
  REQUIRE(double(rounded) > edge);
  for (int axis = 0; axis < 3; ++axis) {
    CAPTURE(axis);
    // The ray runs along `main`, its slope along `axis`; the triangle lies in
    // the plane main = 1 and covers `axis` coordinates below `edge`.
    const int main = (axis + 1) % 3, side = (axis + 2) % 3;
    auto point = [&](double along_axis, double along_side, double along_main) {
      double c[3];
      c[axis] = along_axis;
      c[side] = along_side;
      c[main] = along_main;
      return Vec3{c[0], c[1], c[2]};
    };
    Scene s = scene_looking_down();
    s.camera.from = {0, 0, 0};
    add_polygon(s, {point(-1, -1, 1), point(edge, -1, 1), point(edge, 1, 1), point(-1, 1, 1)});
    const EmbreeScene es(s, EmbreeOptions{});
    TraceHit hit;
    CHECK_FALSE(es.intersect({0, 0, 0}, point(slope, 0, 1), hit));  // the double ray would hit
    CHECK(es.intersect({0, 0, 0}, point(0.099, 0, 1), hit));        // a control that hits
    Vec3 orgs[EmbreeScene::kPacket], dirs[EmbreeScene::kPacket], far[EmbreeScene::kPacket];
    for (int k = 0; k < EmbreeScene::kPacket; ++k) {
      orgs[k] = {0, 0, 0};
      dirs[k] = point(slope, 0.01 * k, 1);
      far[k] = 2.0 * dirs[k];
    }
    TraceHit packed[EmbreeScene::kPacket];
    es.intersect_packet(orgs, dirs, EmbreeScene::kPacket, packed);
    bool blocked[EmbreeScene::kPacket];
    es.occluded_packet(orgs, far, EmbreeScene::kPacket, blocked);
    for (int k = 0; k < EmbreeScene::kPacket; ++k) {
      CAPTURE(k);
      CHECK(packed[k].geom == RTC_INVALID_GEOMETRY_ID);
      CHECK_FALSE(blocked[k]);
    }
  }
}

TEST_CASE("geometry: a ray skips the sphere or tube it departs, in every walk and cache alike") {
  // Rays from inside a sphere and from inside a tube (the rounding a real
  // departure can only approach): without a departure they meet the inside;
  // departing it, the next primitive behind, alone, in a packet through the
  // lane kernels and through the single-ray walk, and the shadow caches
  // never name it for them. The tube is four slices; the rays leave it
  // through every one.
  Scene s = scene_looking_down();
  s.spheres.push_back({{0, 0, 0}, 1.0, 0});
  s.spheres.push_back({{0, 0, -3}, 1.0, 0});
  s.cones.push_back({{-4, 3, 0}, 0.25, {4, 3, 0}, 0.25, 0});
  add_polygon(s, {{-6, 5, -6}, {6, 5, -6}, {6, 5, 6}, {-6, 5, 6}});
  const EmbreeScene es(s, EmbreeOptions{});
  constexpr int kN = EmbreeScene::kPacket;
  // The departures of hits from outside: on the sphere's top, and on the
  // tube's last slice (the departure names all four).
  TraceHit on_sphere, on_tube;
  REQUIRE(es.intersect(es.to_local({0, 0, 5}), {0, 0, -1}, on_sphere));
  REQUIRE(es.intersect(es.to_local({3.9, 0, 0}), {0, 1, 0}, on_tube));
  REQUIRE(on_sphere.geom == EmbreeScene::kSpheres);
  REQUIRE(on_tube.geom == EmbreeScene::kCones);
  const Departure sphere = es.departure_from(on_sphere), tube = es.departure_from(on_tube);
  CHECK(tube.count == 4);
  for (const bool into_tube : {false, true}) {
    CAPTURE(into_tube);
    Vec3 orgs[kN], dirs[kN], segments[kN];
    Departure departs[kN], mixed[kN];
    for (int k = 0; k < kN; ++k) {
      const double a = (k - 7.5) / 7.5;  // -1 .. 1
      orgs[k] = into_tube ? es.to_local(Vec3{3.5 * a, 3 + 0.05 * a, 0.05}) : es.to_local(Vec3{0.3 * a, 0.2, 0.1 * a});
      dirs[k] = into_tube ? Vec3{0.01 * a, 1, 0.02} : Vec3{0.02 * a, 0.01, -1};
      segments[k] = 1.5 * dirs[k];  // past the departed primitive, short of the one behind
      departs[k] = into_tube ? tube : sphere;
      mixed[k] = k % 2 ? departs[k] : Departure{};
    }
    const uint32_t departed_kind = into_tube ? EmbreeScene::kCones : EmbreeScene::kSpheres;
    const uint32_t behind_kind = into_tube ? EmbreeScene::kTriangles : EmbreeScene::kSpheres;
    for (int k = 0; k < kN; ++k) {
      CAPTURE(k);
      TraceHit inside, past;
      REQUIRE(es.intersect(orgs[k], dirs[k], inside));
      CHECK(inside.geom == departed_kind);  // the control: without a departure, the inside
      REQUIRE(es.intersect(orgs[k], dirs[k], past, departs[k]));
      CHECK(past.geom == behind_kind);
      CHECK(past.t > inside.t);
      if (!into_tube) CHECK(past.prim == 1);
      CHECK(es.occluded(orgs[k], segments[k], 1.0));
      CHECK_FALSE(es.occluded(orgs[k], segments[k], 1.0, departs[k]));
    }
    for (const auto origins : {EmbreeScene::Origins::kOnePoint, EmbreeScene::Origins::kScattered}) {
      for (const Departure* lanes : {departs, mixed}) {
        TraceHit packed[kN];
        es.intersect_packet(orgs, dirs, kN, packed, origins, lanes);
        bool together[kN], alone[kN], cached[kN], own_cached[kN];
        es.occluded_together(orgs, segments, kN, together, nullptr, lanes);
        EmbreeScene::ShadowCache* no_caches[kN] = {};
        es.occluded_alone(orgs, segments, kN, alone, no_caches, lanes);
        // Caches that hold the departed primitive (a slice of the tube, the
        // sphere) must not block the rays that depart it.
        EmbreeScene::ShadowCache cache;
        cache.remember({EmbreeScene::kSpheres, 0});
        cache.remember({EmbreeScene::kCones, 2});
        EmbreeScene::ShadowCache light_cache = cache, own[kN];
        es.occluded_together(orgs, segments, kN, cached, &light_cache, lanes);
        EmbreeScene::ShadowCache* own_caches[kN];
        for (int k = 0; k < kN; ++k) own[k] = cache, own_caches[k] = &own[k];
        es.occluded_alone(orgs, segments, kN, own_cached, own_caches, lanes);
        for (int k = 0; k < kN; ++k) {
          CAPTURE(k);
          same_as_alone(es, orgs[k], dirs[k], packed[k], lanes[k]);
          const bool blocked = es.occluded(orgs[k], segments[k], 1.0, lanes[k]);
          CHECK(blocked == (lanes[k].geom == RTC_INVALID_GEOMETRY_ID));
          CHECK(together[k] == blocked);
          CHECK(alone[k] == blocked);
          CHECK(cached[k] == blocked);
          CHECK(own_cached[k] == blocked);
        }
      }
    }
  }
}

TEST_CASE("geometry: rays walked one by one test their caches all at once, each its own primitive") {
  // occluded_alone() tests every ray's cache before any walk, each lane its
  // own sphere, tube slice or triangle piece; a second entry that blocks
  // moves up once, however many rays share its cache, as one ray after
  // another would leave it.
  Scene s = scene_looking_down();
  s.spheres.push_back({{-3, 0, 0}, 0.4, 0});
  s.spheres.push_back({{-1, 0, 0}, 0.4, 0});
  s.spheres.push_back({{-3, 4, -1}, 0.4, 0});  // two on one line, for the shared cache below:
  s.spheres.push_back({{-3, 4, 1}, 0.4, 0});   // Embree's walk meets this one first (here)
  s.cones.push_back({{1, -0.5, 0}, 0.3, {1, 0.5, 0}, 0.3, 0});  // one slice each
  s.cones.push_back({{3, -0.5, 0}, 0.3, {3, 0.5, 0}, 0.15, 0});
  add_polygon(s, {{4.5, -0.5, 0}, {5.5, -0.5, 0}, {5, 0.5, 0}});
  const EmbreeScene es(s, EmbreeOptions{});
  using Occluder = EmbreeScene::Occluder;
  const Occluder none{}, over[] = {{EmbreeScene::kSpheres, 0}, {EmbreeScene::kSpheres, 1}, {EmbreeScene::kCones, 0},
                                   {EmbreeScene::kCones, 1},   {EmbreeScene::kTriangles, 0}, none};
  constexpr int kN = EmbreeScene::kPacket;
  Vec3 orgs[kN], dirs[kN];
  Occluder blocker[kN];
  EmbreeScene::ShadowCache own[kN], *caches[kN];
  for (int k = 0; k < kN; ++k) {
    const int at = k % 6;  // under each primitive in turn, and under none
    orgs[k] = es.to_local({-3.0 + 2 * at + 0.01 * k, 0.02 * (k % 3), -3});
    dirs[k] = {0, 0, 6};
    blocker[k] = over[at];
    const Occluder other = over[(at + 2) % 5];  // another primitive, away from this ray
    switch (k % 4) {
      case 0: own[k].remember(blocker[k]); break;
      case 1: own[k].remember(blocker[k]), own[k].remember(other); break;  // the blocker second
      case 2: own[k].remember(over[(at + 3) % 5]), own[k].remember(other); break;
      default: break;  // empty
    }
    caches[k] = k == 7 ? nullptr : &own[k];
  }
  EmbreeScene::ShadowCache before[kN];
  std::copy(own, own + kN, before);
  bool blocked[kN];
  es.occluded_alone(orgs, dirs, kN, blocked, caches);
  int moved_up = 0;
  for (int k = 0; k < kN; ++k) {
    CAPTURE(k);
    const bool expected = blocker[k].geom != RTC_INVALID_GEOMETRY_ID;
    REQUIRE(es.occluded(orgs[k], dirs[k], 1.0) == expected);  // the control: the ray meets only its primitive
    CHECK(blocked[k] == expected);
    if (k % 4 == 1 && expected) {  // the second entry blocked, and is first now
      CHECK(own[k].first == blocker[k]);
      CHECK(own[k].second == before[k].first);
      ++moved_up;
    }
    if (k % 4 != 1 && k != 7 && expected) CHECK(own[k].first == blocker[k]);  // by the cache, or by the walk
  }
  CHECK(moved_up >= 3);

  // One cache for all: its second entry, one of two spheres every ray
  // passes through, blocks them all and moves up once (once per ray, sixteen
  // times, it would be second again; had the cache not answered, the walk
  // would have put the other sphere first, on this machine).
  const Occluder cached_sphere{EmbreeScene::kSpheres, 2};
  EmbreeScene::ShadowCache shared;
  shared.remember(cached_sphere);
  shared.remember(over[2]);  // a tube they miss, first
  for (int k = 0; k < kN; ++k) {
    orgs[k] = es.to_local({-3.0 + 0.01 * k, 4 + 0.01 * (k % 4), -3});
    caches[k] = &shared;
  }
  es.occluded_alone(orgs, dirs, kN, blocked, caches);
  CHECK(std::all_of(blocked, blocked + kN, [](bool b) { return b; }));
  CHECK(shared.first == cached_sphere);
  CHECK(shared.second == over[2]);
}
