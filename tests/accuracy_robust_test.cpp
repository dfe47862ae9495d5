// Ill-conditioned intersections, asked directly of the EmbreeScene and checked
// against long-double references computed for the very float ray Embree sees:
// grazing rays at sphere silhouettes and cone rims, rays parallel to a cone's
// axis, small spheres far from the camera, and rays through the shared edges
// and vertices of a closed triangle mesh (Embree's WatertightTest idea: from
// inside, no ray may escape), with and without RTC_SCENE_FLAG_ROBUST.
#include <doctest/doctest.h>

#include <cmath>
#include <cstdio>
#include <random>

#include "study/image_metrics.h"
#include "tests/accuracy_scenes.h"
#include "tracer/embree_scene.h"

namespace rayfarm {
namespace {

using test::NffText;
using Real = long double;

// The ray as Embree traces it: origin and direction rounded to float.
Vec3 as_float(const Vec3& v) {
  return {static_cast<float>(v.x), static_cast<float>(v.y), static_cast<float>(v.z)};
}

// Reference sphere hit in long double for the float-rounded ray: nearest
// t > 0, or -1 on a miss. Also the impact parameter (distance of the line from
// the centre), so tests can skip rays that graze within rounding.
Real reference_sphere(const Vec3& c, double r, const Vec3& o, const Vec3& d, Real& impact) {
  const Real fx = Real(o.x) - c.x, fy = Real(o.y) - c.y, fz = Real(o.z) - c.z;
  const Real a = Real(d.x) * d.x + Real(d.y) * d.y + Real(d.z) * d.z;
  const Real b = (fx * d.x + fy * d.y + fz * d.z) / a;  // -t of the closest point
  const Real lx = fx - b * d.x, ly = fy - b * d.y, lz = fz - b * d.z;
  impact = std::sqrt(lx * lx + ly * ly + lz * lz);
  const Real h2 = Real(r) * r - impact * impact;
  if (h2 < 0) return -1;
  const Real h = std::sqrt(h2 / a);
  if (-b - h > 0) return -b - h;
  if (-b + h > 0) return -b + h;
  return -1;
}

Scene sphere_scene(Vec3 eye, Vec3 c, double r) {
  return NffText().view(eye, c, {0, 0, 1}, 45, 64).fill({1, 1, 1}, 1, 0, 0, 0, 1).sphere(c, r).parse();
}

struct SphereTally {
  int rays = 0, wrong_hit_or_miss = 0, ambiguous = 0;
  double worst_rel_t = 0;
};

// Rays from the camera through points around a sphere of radius r at world
// centre c, at impact parameters r * (1 + delta); compares every answer with
// the long-double reference.
SphereTally probe_sphere(const Vec3& eye, const Vec3& c, double r, std::initializer_list<double> deltas,
                         int per_delta, uint64_t seed) {
  const EmbreeScene es(sphere_scene(eye, c, r), EmbreeOptions{});
  const Vec3 lc = es.to_local(c);  // camera at the local origin
  const Vec3 view = normalize(lc);
  const Vec3 u = normalize(cross(view, std::fabs(view.z) < 0.9 ? Vec3{0, 0, 1} : Vec3{1, 0, 0}));
  const Vec3 v = cross(view, u);
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> angle(0, 6.283185307179586);
  SphereTally tally;
  for (double delta : deltas) {
    for (int i = 0; i < per_delta; ++i) {
      const double a = angle(rng);
      const Vec3 target = lc + (u * std::cos(a) + v * std::sin(a)) * (r * (1 + delta));
      const Vec3 o{}, d = as_float(target);
      Real impact = 0;
      const Real t_ref = reference_sphere(lc, r, o, d, impact);
      ++tally.rays;
      // Within a few float ulps of the silhouette either answer is right.
      if (std::fabs(double(impact) - r) < 1e-6 * length(lc)) {
        ++tally.ambiguous;
        continue;
      }
      TraceHit hit;
      const bool found = es.intersect(o, d, hit);
      if (found != (t_ref > 0)) {
        ++tally.wrong_hit_or_miss;
        continue;
      }
      if (found) tally.worst_rel_t = std::max(tally.worst_rel_t, double(std::fabs(hit.t - t_ref) / t_ref));
    }
  }
  return tally;
}

}  // namespace

TEST_CASE("accuracy: grazing rays at a sphere's silhouette agree with a long-double reference") {
  // Impact parameters from 1% outside to 1e-5 inside the silhouette.
  const SphereTally t = probe_sphere({0, 0, 0}, {0.5, 10, 0.3}, 1.0,
                                     {1e-2, 1e-3, 1e-4, 1e-5, -1e-5, -1e-4, -1e-3, -1e-2}, 500, 11);
  INFO("rays " << t.rays << ", ambiguous " << t.ambiguous << ", worst relative t error " << t.worst_rel_t);
  CHECK(t.wrong_hit_or_miss == 0);
  CHECK(t.worst_rel_t < 1e-6);  // t comes back as a float: ~6e-8 is its resolution
}

TEST_CASE("accuracy: small spheres far from the camera agree with a long-double reference") {
  // Radius 1e-3 at 1e3 and 1e4 units: the textbook quadratic loses every digit
  // here, Ray Tracing Gems ch. 7's form must not.
  for (const double dist : {1e3, 1e4}) {
    const Vec3 eye{1e5, 2e5, -3e4};  // far from the world origin as well
    const Vec3 c = eye + normalize(Vec3{0.3, 1, 0.2}) * dist;
    const SphereTally t = probe_sphere(eye, c, 1e-3, {-0.9, -0.5, -0.1, -1e-3, 1e-3, 0.1}, 300, 12);
    INFO("distance " << dist << ": rays " << t.rays << ", ambiguous " << t.ambiguous << ", worst rel t "
                     << t.worst_rel_t);
    CHECK(t.wrong_hit_or_miss == 0);
    CHECK(t.worst_rel_t < 1e-6);
  }
}

TEST_CASE("accuracy: cone rims and grazing sides and rays parallel to the axis") {
  // A cylinder and a cone along +z from z = 0 to 1; camera on the -y side.
  const Vec3 eye{0, -5, 0.5};
  for (const double apex_r : {0.5, 0.1}) {
    const Scene scene = NffText()
                            .view(eye, {0, 0, 0.5}, {0, 0, 1}, 45, 64)
                            .fill({1, 1, 1}, 1, 0, 0, 0, 1)
                            .cone({0, 0, 0}, 0.5, {0, 0, 1}, apex_r)
                            .parse();
    const EmbreeScene es(scene, EmbreeOptions{});
    const auto local = [&](Vec3 w) { return es.to_local(w); };
    TraceHit hit;
    int wrong = 0, rays = 0;
    // Horizontal rays just below / above the top rim and the bottom rim.
    for (const double delta : {1e-3, 1e-4, 1e-5}) {
      for (const double z : {1.0, 0.0}) {
        const bool top = z == 1.0;
        const double inside_z = top ? z - delta : z + delta, outside_z = top ? z + delta : z - delta;
        ++rays;
        wrong += !es.intersect(local({0, -5, inside_z}), {0, 1, 0}, hit);
        ++rays;
        wrong += es.intersect(local({0, -5, outside_z}), {0, 1, 0}, hit);
      }
    }
    CHECK(wrong == 0);
    // Grazing the side: vertical plane offset x = r(z) * (1 -+ delta) at z = 0.5.
    const double r_mid = 0.5 + (apex_r - 0.5) * 0.5;
    for (const double delta : {1e-3, 1e-4, 1e-5}) {
      CHECK(es.intersect(local({r_mid * (1 - delta), -5, 0.5}), {0, 1, 0}, hit));
      CHECK_FALSE(es.intersect(local({r_mid * (1 + delta), -5, 0.5}), {0, 1, 0}, hit));
    }
    // Parallel to the axis, from below, at radius rho: a cylinder (open ends) is
    // never hit; a cone is hit once where r(s) = rho, at s = (0.5 - rho) / slope.
    for (const double rho : {0.0, 0.05, 0.2, 0.3, 0.45}) {
      const Vec3 o = local({rho, 0, -1});
      const bool found = es.intersect(o, {0, 0, 1}, hit);
      if (apex_r == 0.5 || rho < apex_r) {
        CHECK_FALSE(found);
      } else {
        REQUIRE(found);
        const double s = (0.5 - rho) / (0.5 - apex_r);
        CHECK(hit.t == doctest::Approx(1 + s).epsilon(1e-6));
        CHECK(is_finite(hit.ng));
      }
    }
    (void)rays;
  }
}

namespace {

// Escapes from inside a closed mesh, per kind of aim point.
struct EscapeCount {
  long rays = 0, escaped = 0;
  double percent() const { return rays ? 100.0 * escaped / rays : 0; }
};

enum Aim { kVertex, kEdgeMidpoint, kEdgePoint, kRandomDirection, kAims };
const char* const kAimNames[kAims] = {"vertices", "edge midpoints", "random edge points", "random directions"};

}  // namespace

TEST_CASE("accuracy: rays from inside a closed tessellated sphere through its edges and vertices") {
  // The camera sits inside a closed UV sphere centred at the world origin, so
  // local vertex positions are the exact floats the rays aim at.
  NffText nff;
  nff.view({0, 0, 0}, {0, 1, 0}, {0, 0, 1}, 45, 64).fill({1, 1, 1}, 1, 0, 0, 0, 1);
  const auto tris = test::tessellated_sphere({0, 0, 0}, 1.0, 48, 96);
  for (const auto& tri : tris) nff.polygon(tri);
  const Scene scene = nff.parse();
  std::vector<Vec3> aims[kAims];
  std::mt19937_64 rng(21);
  std::uniform_real_distribution<double> unit(0, 1), sym(-1, 1);
  for (const auto& tri : tris) {
    for (int e = 0; e < 3; ++e) {
      const Vec3 a = tri[e], b = tri[(e + 1) % 3];
      const double s = unit(rng);
      aims[kVertex].push_back(a);
      aims[kEdgeMidpoint].push_back((a + b) * 0.5);
      aims[kEdgePoint].push_back(a * (1 - s) + b * s);
      aims[kRandomDirection].push_back({sym(rng), sym(rng), sym(rng)});
    }
  }
  // From the centre a ray passes exactly through its aim point; from the other
  // origins the float direction misses it by rounding.
  const Vec3 origins[] = {{0, 0, 0}, {0.31, -0.12, 0.05}, {-0.4, 0.27, -0.33}, {1e-3, 2e-3, 0.6}};
  EscapeCount count[2][kAims];
  for (const bool robust : {false, true}) {
    EmbreeOptions options;
    options.robust_bvh = robust;
    const EmbreeScene es(scene, options);
    for (int aim = 0; aim < kAims; ++aim) {
      EscapeCount& c = count[robust][aim];
      for (const Vec3& o : origins) {
        for (const Vec3& t : aims[aim]) {
          TraceHit hit;
          ++c.rays;
          const Vec3 dir = aim == kRandomDirection ? t : t - o;
          if (!es.intersect(es.to_local(o), dir, hit)) ++c.escaped;
        }
      }
      char line[200];
      std::snprintf(line, sizeof line, "robust %-3s through %-18s: %6ld of %6ld rays escaped (%.4f%%), %zu triangles",
                    robust ? "on" : "off", kAimNames[aim], c.escaped, c.rays, c.percent(), tris.size());
      MESSAGE(line);
    }
  }
  // Measured (Embree 3.13, 9024 triangles): without robust mode 17% of the rays
  // aimed exactly at a vertex and 7% of those aimed at an edge escape; robust
  // mode lets none through an edge and 0.24% through exact vertices. Random
  // directions never escape in either mode, so renders rarely show the gaps.
  CHECK(count[1][kEdgeMidpoint].escaped == 0);
  CHECK(count[1][kEdgePoint].escaped == 0);
  CHECK(count[1][kVertex].percent() < 1.0);
  CHECK(count[0][kRandomDirection].escaped == 0);
  CHECK(count[1][kRandomDirection].escaped == 0);
  for (int aim = 0; aim < kAims; ++aim) CHECK(count[1][aim].escaped <= count[0][aim].escaped);
}

}  // namespace rayfarm
