// Pixels do not depend on the SIMD width Embree runs at: the paper scenes, the
// hard cases of the accuracy tests and random rays (grazing ones included)
// give the same bits with Embree and rayfarm's lane kernels capped at SSE4.2,
// at AVX2 and at this CPU's widest kernels (AVX-512 where available). Without
// exact hits and an
// order-free tie rule (embree_scene.cpp) 0.003-21% of the paper scenes' pixels
// differed between these widths.
#include <doctest/doctest.h>

#include <cstring>
#include <random>
#include <string>
#include <vector>

#include "tests/accuracy_scenes.h"
#include "tests/test_paths.h"
#include "tracer/embree_scene.h"
#include "tracer/error.h"
#include "tracer/nff_reader.h"

namespace rayfarm {
namespace {

using test::NffText;

// "" is no cap: the widest kernels this CPU runs.
const char* const kWidths[] = {"sse4.2", "avx2", ""};

std::vector<float> render_at(const Scene& scene, int size, int spp, const char* max_isa, double adaptive = 0) {
  RenderSettings settings = test::small_settings(size, spp, 1);
  settings.max_isa = max_isa;
  settings.adaptive_contrast = adaptive;
  return test::render_image(scene, settings);
}

// Bitwise equality of float images (== would call -0 and 0 equal).
size_t differing_pixels(const std::vector<float>& a, const std::vector<float>& b) {
  REQUIRE(a.size() == b.size());
  size_t n = 0;
  for (size_t i = 0; i < a.size(); i += 3) n += std::memcmp(&a[i], &b[i], 3 * sizeof(float)) != 0;
  return n;
}

void check_same_at_every_width(const Scene& scene, int size, int spp, double adaptive = 0) {
  const std::vector<float> widest = render_at(scene, size, spp, "", adaptive);
  for (const char* width : kWidths) {
    CAPTURE(width);
    CHECK(differing_pixels(render_at(scene, size, spp, width, adaptive), widest) == 0);
  }
}

// Ties and near-ties: coplanar overlapping polygons, coincident spheres and
// cones, a sphere touching a polygon, all in one view.
Scene tie_scene() {
  NffText nff;
  nff.background({0.1, 0.1, 0.2})
      .view({0, -5, 2}, {0, 0, 0.5}, {0, 0, 1}, 45, 48)
      .light({3, -4, 5})
      .fill({0.9, 0.2, 0.2}, 0.8, 0.2, 10, 0, 1)
      .polygon({{2, 2, 0}, {-2, 2, 0}, {-2, -2, 0}, {2, -2, 0}})
      .sphere({-1, 0, 0.5}, 0.5)
      .cone({1, 0, 0}, 0.4, {1, 0, 1}, 0.4)
      .fill({0.2, 0.9, 0.2}, 0.8, 0.4, 10, 0, 1)
      .polygon({{1.5, 1.5, 0}, {-2.5, 1.5, 0}, {-2.5, -1.5, 0}, {1.5, -1.5, 0}})
      .sphere({-1, 0, 0.5}, 0.5)
      .cone({1, 0, 0}, 0.4, {1, 0, 1}, 0.4);
  return nff.parse();
}

// The camera at the centre of a closed tessellated sphere: every ray meets it
// at an edge, a vertex or inside a triangle (the watertight test's home ground).
Scene inside_mesh_scene() {
  NffText nff;
  nff.view({0, 0, 0}, {0, 1, 0.3}, {0, 0, 1}, 100, 48).light({0.2, 0.1, 0.3}).fill({1, 1, 1}, 0.7, 0.3, 5, 0, 1);
  for (const auto& tri : test::tessellated_sphere({0, 0, 0}, 1.0, 24, 48)) nff.polygon(tri);
  return nff.parse();
}

// Grazing rays: a floor seen edge-on from its own height and sub-pixel spheres
// far away.
Scene grazing_scene() {
  NffText nff;
  nff.view({0, -10, 1e-4}, {0, 0, 0}, {0, 0, 1}, 30, 48).light({2, -3, 4}).fill({0.8, 0.8, 0.8}, 0.8, 0.2, 5, 0, 1);
  nff.polygon({{5, 5, 0}, {-5, 5, 0}, {-5, -5, 0}, {5, -5, 0}});
  for (int i = 0; i < 20; ++i) nff.sphere({-1.9 + 0.2 * i, 40, 0.3 + 0.05 * i}, 0.02);
  return nff.parse();
}

}  // namespace

TEST_CASE("simd width: the five paper scenes render the same bits at SSE4.2, AVX2 and native width") {
  for (const char* name : {"balls", "gears", "mount", "rings", "tetra"}) {
    CAPTURE(name);
    check_same_at_every_width(read_nff_file(test::source_dir() + "/scenes/" + name + ".nff"), 64, 4);
  }
}

// Adaptive sampling decides from the corner samples' values, which are the
// same bits at every width, so it refines the same pixels.
TEST_CASE("simd width: adaptive renders of the five paper scenes are the same bits at every width") {
  for (const char* name : {"balls", "gears", "mount", "rings", "tetra"}) {
    CAPTURE(name);
    check_same_at_every_width(read_nff_file(test::source_dir() + "/scenes/" + name + ".nff"), 64, 16, 0.1);
  }
}

TEST_CASE("simd width: the hard cases render the same bits at every width") {
  check_same_at_every_width(test::contact_scene(1, {}), 48, 4);
  check_same_at_every_width(test::contact_scene(1, {1e6, -0.7e6, 0.4e6}), 48, 4);
  check_same_at_every_width(test::contact_scene(1e-3, {}), 48, 4);
  check_same_at_every_width(tie_scene(), 48, 4);
  check_same_at_every_width(inside_mesh_scene(), 48, 4);
  check_same_at_every_width(grazing_scene(), 48, 4);
}

TEST_CASE("simd width: the tie rule picks the lower primitive, not the one met first") {
  // Two coplanar quads overlap; the first one in the file (the lower
  // primitive indices) must win wherever both are hit, at every width.
  const Scene scene = tie_scene();
  for (const char* width : kWidths) {
    CAPTURE(width);
    EmbreeOptions options;
    options.max_isa = width;
    const EmbreeScene es(scene, options);
    TraceHit hit;
    REQUIRE(es.intersect(es.to_local({0, 0, 3}), {0.01, 0.02, -1}, hit));
    CHECK(hit.geom == EmbreeScene::kTriangles);
    CHECK(hit.prim < 2);  // the first quad's two triangles
    REQUIRE(es.intersect(es.to_local({-1, 0, 3}), {0, 0, -1}, hit));
    CHECK(hit.geom == EmbreeScene::kSpheres);
    CHECK(hit.prim == 0);
  }
}

TEST_CASE("simd width: random and grazing rays at mount and gears hit the same primitive at the same t") {
  // Random origins and directions, and rays aimed at triangles almost in
  // their plane (1e-9 to 1e-2 out of it), compared field by field.
  for (const char* name : {"mount", "gears"}) {
    CAPTURE(name);
    const Scene scene = read_nff_file(test::source_dir() + "/scenes/" + name + ".nff");
    std::vector<Vec3> orgs, dirs;
    std::mt19937_64 rng(13);
    std::uniform_real_distribution<double> sym(-1, 1), unit(0, 1);
    for (int i = 0; i < 3000; ++i) {
      orgs.push_back({sym(rng) * 2, sym(rng) * 2, sym(rng) * 2});
      dirs.push_back({sym(rng), sym(rng), sym(rng)});
      // Grazing: from a point beside a random polygon's plane, towards its centre.
      const Polygon& p = scene.polygons[rng() % scene.polygons.size()];
      const Vec3 a = scene.vertices[p.first], b = scene.vertices[p.first + 1], c = scene.vertices[p.first + 2];
      const Vec3 n = normalize(cross(b - a, c - a)), centre = (a + b + c) * (1.0 / 3);
      const Vec3 along = normalize(b - a);
      const double lift = std::pow(10.0, -9 + 7 * unit(rng));
      orgs.push_back(centre - along * 3.0 + n * (lift * 3.0));
      dirs.push_back(along - n * lift);
    }
    std::vector<TraceHit> reference;
    std::vector<bool> reference_blocked;
    for (const char* width : {"", "avx2", "sse4.2"}) {
      CAPTURE(width);
      EmbreeOptions options;
      options.max_isa = width;
      const EmbreeScene es(scene, options);
      size_t differ = 0, hits = 0;
      for (size_t i = 0; i < orgs.size(); ++i) {
        TraceHit h;
        if (!es.intersect(es.to_local(orgs[i]), dirs[i], h)) h.geom = ~0u;
        const bool blocked = es.occluded(es.to_local(orgs[i]), dirs[i], 1.0);
        hits += h.geom != ~0u;
        if (reference.size() < orgs.size()) {
          reference.push_back(h);
          reference_blocked.push_back(blocked);
          continue;
        }
        const TraceHit& r = reference[i];
        const bool same = h.geom == r.geom && (h.geom == ~0u || (h.prim == r.prim && h.t == r.t && h.u == r.u &&
                                                                  h.v == r.v && h.ng == r.ng));
        differ += !same || blocked != reference_blocked[i];
      }
      CHECK(hits > orgs.size() / 4);  // the rays do meet the scene
      CHECK(differ == 0);
    }
  }
}

TEST_CASE("simd width: an unknown max_isa is an error naming the accepted values") {
  Scene scene = test::contact_scene(1, {});
  CHECK_THROWS_WITH_AS(render_at(scene, 8, 1, "avx3"),
                       doctest::Contains("max_isa must be one of sse2, sse4.2, avx, avx2, avx512"), InputError);
}

}  // namespace rayfarm
