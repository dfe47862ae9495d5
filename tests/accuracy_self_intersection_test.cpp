// Self-intersection (pbrt's Triangle.Reintersect idea): spawn secondary rays
// from thousands of seeded random hits on spheres, cones, triangles and a
// concave polygon, with origins moved off the surface by the Wachter-Binder
// offset (ray_offset.h, Ray Tracing Gems ch. 6) exactly as the integrator does,
// and check that no ray re-hits the surface it leaves. Direct queries on the
// EmbreeScene, one primitive per scene, placed near and far from the camera.
#include <doctest/doctest.h>

#include <cmath>
#include <random>
#include <string>

#include "tests/accuracy_scenes.h"
#include "tracer/embree_scene.h"
#include "tracer/ray_offset.h"
#include "tracer/shapes.h"

namespace rayfarm {
namespace {

using test::NffText;

struct Rng {
  std::mt19937_64 gen;
  explicit Rng(uint64_t seed) : gen(seed) {}
  double uniform(double a = 0, double b = 1) { return std::uniform_real_distribution<double>(a, b)(gen); }
  Vec3 unit() {  // uniform on the sphere
    const double z = uniform(-1, 1), phi = uniform(0, 6.283185307179586);
    const double s = std::sqrt(1 - z * z);
    return {s * std::cos(phi), s * std::sin(phi), z};
  }
  // Direction in the hemisphere around unit `n` with cos >= min_cos.
  Vec3 hemisphere(const Vec3& n, double min_cos) {
    for (;;) {
      const Vec3 d = unit();
      const double c = dot(d, n);
      if (std::fabs(c) >= min_cos) return c > 0 ? d : -d;
    }
  }
};

Vec3 reflect(const Vec3& d, const Vec3& n) { return d - n * (2 * dot(d, n)); }

// Snell refraction of unit d through unit n (facing d), eta = n_from / n_to;
// false on total internal reflection.
bool refract(const Vec3& d, const Vec3& n, double eta, Vec3& out) {
  const double cos_i = -dot(d, n);
  const double k = 1 - eta * eta * (1 - cos_i * cos_i);
  if (k < 0) return false;
  out = d * eta + n * (eta * cos_i - std::sqrt(k));
  return true;
}

struct Tally {
  int hits = 0;           // primary hits the rays were spawned from
  int spawned = 0;        // secondary rays traced
  int self_hits = 0;      // re-hits of the surface left (must stay 0)
  int false_shadow = 0;   // shadow rays occluded by the surface they leave
  int lost_inside = 0;    // rays into a closed solid that found no far side
  std::string first_failure;

  void fail(int& counter, const std::string& what) {
    if (counter++ == 0 && first_failure.empty()) first_failure = what;
  }
};

// What a test knows about its one object.
struct Solid {
  bool closed = false;  // sphere, tessellated sphere: a ray going in must find a far side
  bool planar = false;  // polygon: any hit after leaving it is a self-hit
  bool mesh = false;    // triangles: an inward ray may meet a neighbour near an edge, never its own
  double size = 1;      // radius of the bounding sphere the test rays aim at
  // Cone axis (for the local radius that bounds legitimate inner hits).
  bool cone = false;
  Vec3 axis_a{}, axis_b{};

  static Solid sphere(double r) { return with([&](Solid& s) { s.closed = true; s.size = r; }); }
  static Solid mesh_sphere(double r) { return with([&](Solid& s) { s.closed = s.mesh = true; s.size = r; }); }
  static Solid polygon(double size) { return with([&](Solid& s) { s.planar = true; s.size = size; }); }
  static Solid open_cone(double size, Vec3 a, Vec3 b) {
    return with([&](Solid& s) { s.size = size; s.cone = true; s.axis_a = a; s.axis_b = b; });
  }
  template <class F>
  static Solid with(F&& set) {
    Solid s;
    set(s);
    return s;
  }
};

// Distance below which a hit on the inner side of a convex surface counts as a
// self-hit: 1% of the local radius. Legitimate inner chords are longer because
// inward test directions keep cos >= kMinCos with the normal.
constexpr double kMinCos = 0.05;

double local_radius(const Solid& s, const Vec3& p) {
  if (!s.cone) return s.size;
  const Vec3 axis = normalize(s.axis_b - s.axis_a);
  const Vec3 q = p - s.axis_a;
  return length(q - axis * dot(q, axis));
}

// Traces one spawned ray and classifies it. `outward` is the unit outward
// normal (either side of a plane is "outward").
void check_ray(const EmbreeScene& es, const Vec3& org, const Vec3& dir, const Vec3& outward, const Vec3& p,
               uint32_t hit_prim, const Solid& solid, const std::string& where, Tally& tally) {
  ++tally.spawned;
  TraceHit h2;
  const bool found = es.intersect(org, dir, h2);
  const double dist = found ? h2.t * length(dir) : 0;
  if (solid.planar || dot(dir, outward) > 0) {
    // Leaving a plane, or the outside of a convex surface: nothing to meet.
    if (found) tally.fail(tally.self_hits, "outgoing ray re-hit at distance " + std::to_string(dist) + ", " + where);
    return;
  }
  if (solid.closed && !found) tally.fail(tally.lost_inside, "ray into the closed solid escaped, " + where);
  if (solid.mesh) {
    if (found && h2.prim == hit_prim) {
      tally.fail(tally.self_hits, "inward ray re-hit its triangle at distance " + std::to_string(dist) + ", " + where);
    }
    return;
  }
  if (dot(normalize(dir), -outward) < kMinCos) return;  // grazing inner chord: no sharp expectation
  if (found && dist < 0.01 * local_radius(solid, p)) {
    tally.fail(tally.self_hits, "inward ray re-hit at distance " + std::to_string(dist) + ", " + where);
  }
}

// Spawns mirror, random, shadow and refraction rays from the hit, with origins
// offset as whitted.cpp does: `front` on the ray's side, `back` beyond.
void spawn_from(const EmbreeScene& es, const Vec3& org, const Vec3& dir, const TraceHit& hit,
                const Solid& solid, Rng& rng, Tally& tally) {
  const Vec3 d = normalize(dir);
  const Vec3 ng = normalize(hit.ng);
  const bool from_outside = dot(d, ng) < 0;
  const Vec3 nf = from_outside ? ng : -ng;  // towards the ray's side
  const Vec3 p = org + hit.t * dir;
  const double scale = offset_scale(p, org);
  const Vec3 front = offset_ray_origin(p, nf, scale), back = offset_ray_origin(p, -nf, scale);
  // For a plane the side the ray leaves to is "outward" whichever it is.
  const Vec3 out_front = solid.planar ? nf : ng, out_back = solid.planar ? -nf : ng;
  const std::string where = "hit at t=" + std::to_string(hit.t) + " prim " + std::to_string(hit.prim);

  check_ray(es, front, reflect(d, nf), out_front, p, hit.prim, solid, where, tally);
  check_ray(es, front, rng.hemisphere(nf, 1e-3), out_front, p, hit.prim, solid, where, tally);
  Vec3 t_dir;
  if (!refract(d, nf, from_outside ? 1 / 1.5 : 1.5, t_dir)) t_dir = reflect(d, nf);
  if (dot(t_dir, nf) < 0) check_ray(es, back, t_dir, out_back, p, hit.prim, solid, where, tally);
  check_ray(es, back, rng.hemisphere(-nf, kMinCos), out_back, p, hit.prim, solid, where, tally);
  if (solid.planar || from_outside) {
    // Shadow ray towards a light 10 sizes away on the outer side.
    ++tally.spawned;
    if (es.occluded(front, rng.hemisphere(nf, 1e-3) * (10 * solid.size), 1.0f)) {
      tally.fail(tally.false_shadow, "shadow ray occluded by its own surface, " + where);
    }
  }
}

// Shoots `n` random rays at the bounding sphere of the object (from outside and,
// for closed solids, from inside) and spawns from every hit.
Tally property_run(const Scene& scene, const Vec3& center_world, const Solid& solid, int n, uint64_t seed,
                   bool robust = false) {
  EmbreeOptions options;
  options.robust_bvh = robust;
  const EmbreeScene es(scene, options);
  const Vec3 center = es.to_local(center_world);
  Rng rng(seed);
  Tally tally;
  for (int i = 0; i < n; ++i) {
    // Half the rays come from outside, half (for closed solids) from inside.
    const bool inside = solid.closed && (i % 2 == 1);
    const Vec3 org = inside ? center + rng.unit() * (0.3 * solid.size)
                            : center + rng.unit() * (4 * solid.size);
    const Vec3 target = center + rng.unit() * (0.9 * solid.size);
    const Vec3 dir = target - org;
    TraceHit hit;
    if (!es.intersect(org, dir, hit)) continue;
    ++tally.hits;
    spawn_from(es, org, dir, hit, solid, rng, tally);
  }
  return tally;
}

void report(const char* what, const Tally& t) {
  INFO(std::string(what) << ": " << t.hits << " hits, " << t.spawned << " spawned rays; first failure: " << t.first_failure);
  CHECK(t.hits > 1000);
  CHECK(t.self_hits == 0);
  CHECK(t.false_shadow == 0);
  CHECK(t.lost_inside == 0);
}

Scene one_sphere(Vec3 c, double r, Vec3 eye) {
  return NffText()
      .view(eye, c, {0, 0, 1}, 45, 64)
      .fill({1, 1, 1}, 1, 0, 0, 0, 1)
      .sphere(c, r)
      .parse();
}

}  // namespace

TEST_CASE("accuracy: rays spawned from sphere hits never re-hit their sphere") {
  const Solid solid = Solid::sphere(0.7);
  report("sphere near the camera", property_run(one_sphere({3, 1, -2}, 0.7, {0, 0, 0}), {3, 1, -2}, solid, 4000, 1));
  // Far from the world origin (the camera-relative build must keep precision).
  const Vec3 far{1.0e5, -2.5e5, 3.0e4};
  report("sphere far from the origin", property_run(one_sphere(far, 0.7, far + Vec3{5, 3, 2}), far, solid, 4000, 2));
  // Small sphere far from the camera: hits carry large coordinates.
  const Solid tiny = Solid::sphere(0.01);
  report("small sphere 200 units away",
         property_run(one_sphere({200, 0, 0}, 0.01, {0, 0, 0}), {200, 0, 0}, tiny, 4000, 3));
}

TEST_CASE("accuracy: rays spawned from cone hits never re-hit their cone") {
  for (const double apex_r : {0.5, 0.15, 0.0}) {  // cylinder, cone, pointed cone
    const Vec3 base{2, 1, -1}, apex{2.6, 1.8, 0.2};
    const Scene scene = NffText()
                            .view({0, 0, 0}, base, {0, 0, 1}, 45, 64)
                            .fill({1, 1, 1}, 1, 0, 0, 0, 1)
                            .cone(base, 0.5, apex, apex_r)
                            .parse();
    const std::string what = "cone with apex radius " + std::to_string(apex_r);
    const Solid solid = Solid::open_cone(0.5, base, apex);
    report(what.c_str(), property_run(scene, (base + apex) * 0.5, solid, 6000, 4));
  }
}

TEST_CASE("accuracy: rays spawned from a closed triangle mesh never re-hit their triangle") {
  NffText nff;
  const Vec3 c{1.5, -2, 0.5};
  nff.view({0, 0, 0}, c, {0, 0, 1}, 45, 64).fill({1, 1, 1}, 1, 0, 0, 0, 1);
  for (const auto& tri : test::tessellated_sphere(c, 0.8, 12, 24)) nff.polygon(tri);
  report("tessellated sphere", property_run(nff.parse(), c, Solid::mesh_sphere(0.8), 4000, 5));
}

TEST_CASE("accuracy: rays spawned from a concave polygon never re-hit its plane") {
  // A 12-pointed star (concave, ear-clipped into triangles), tilted and away
  // from the origin; any hit after leaving the polygon is a self-hit.
  NffText nff;
  const Vec3 c{-3, 4, 2};
  nff.view({0, 0, 0}, c, {0, 0, 1}, 45, 64).fill({1, 1, 1}, 1, 0, 0, 0, 1);
  std::vector<Vec3> star;
  const Vec3 u = normalize(Vec3{1, 0.3, -0.2}), v = normalize(cross(Vec3{0.2, 0.1, 1}, u));
  for (int i = 0; i < 24; ++i) {
    const double a = 6.283185307179586 * i / 24, r = (i % 2 == 0) ? 1.0 : 0.45;
    star.push_back(c + u * (r * std::cos(a)) + v * (r * std::sin(a)));
  }
  nff.polygon(star);
  report("concave star polygon", property_run(nff.parse(), c, Solid::polygon(1.0), 16000, 6));
}

}  // namespace rayfarm
