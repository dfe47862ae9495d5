// Renderer: determinism across bands/threads, effect derivation (no ray kinds a
// scene cannot cause), camera conventions, smooth `pp` normals, settings
// validation, no NaN in the output, and translation invariance.
#include <doctest/doctest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numeric>
#include <random>
#include <thread>

#include "tracer/camera.h"
#include "tracer/error.h"
#include "tracer/renderer.h"
#include "tracer/whitted.h"
#include "tests/render_paths.h"

using namespace rayfarm;
using rayfarm::test::same_bytes;

namespace {

uint32_t add_material(Scene& s, Vec3 color, double kd, double ks, double t = 0, double ior = 1) {
  s.materials.push_back({color, kd, ks, 20.0, t, ior});
  return static_cast<uint32_t>(s.materials.size() - 1);
}

void add_polygon(Scene& s, std::initializer_list<Vec3> verts, uint32_t material, const Vec3& offset) {
  Polygon p;
  p.first = static_cast<uint32_t>(s.vertices.size());
  p.count = static_cast<uint32_t>(verts.size());
  p.material = material;
  for (const Vec3& v : verts) s.vertices.push_back(v + offset);
  s.polygons.push_back(p);
}

// A few spheres (mirror, glass), an open cone whose apex faces the camera, and a
// floor polygon, lit by two lights; everything shifted by `offset`.
Scene small_scene(const Vec3& offset = {}) {
  Scene s;
  s.background = {0.1, 0.2, 0.4};
  s.camera.from = Vec3{0, -6, 2} + offset;
  s.camera.at = Vec3{0, 0, 0.5} + offset;
  s.camera.up = {0, 0, 1};
  s.camera.width = s.camera.height = 64;
  s.lights.push_back({Vec3{4, -3, 6} + offset, {1, 1, 1}});
  s.lights.push_back({Vec3{-3, -2, 5} + offset, {1, 1, 1}});
  const uint32_t floor = add_material(s, {1, 0.8, 0.5}, 0.8, 0);
  const uint32_t mirror = add_material(s, {0.9, 0.9, 1}, 0.4, 0.6);
  const uint32_t glass = add_material(s, {1, 1, 1}, 0.1, 0.1, 0.9, 1.5);
  add_polygon(s, {{-5, -5, 0}, {5, -5, 0}, {5, 5, 0}, {-5, 5, 0}}, floor, offset);
  s.spheres.push_back({Vec3{-1, 0, 1} + offset, 1.0, mirror});
  s.spheres.push_back({Vec3{1.2, -1, 0.7} + offset, 0.7, glass});
  s.cones.push_back({Vec3{2, 1, 0} + offset, 0.6, Vec3{2, 0, 2} + offset, 0.0, mirror});
  return s;
}

RenderSettings small_settings(int threads) {
  RenderSettings rs;
  rs.width = rs.height = 64;
  rs.spp = 4;
  rs.threads = threads;
  rs.seed = 7;
  return rs;
}

std::vector<float> render_all(const Scene& scene, const RenderSettings& rs, RayStats* stats = nullptr) {
  const Renderer r(scene, rs);
  std::vector<float> rgb;
  r.render_rows(0, rs.height, rgb, stats);
  return rgb;
}

}  // namespace

TEST_CASE("render: full image, bands in random order and 1 or 2 threads are byte-identical") {
  const Scene scene = small_scene();
  RayStats full_stats;
  const std::vector<float> full = render_all(scene, small_settings(2), &full_stats);
  REQUIRE(full.size() == size_t(64 * 64 * 3));
  CHECK(full_stats.eye == 64u * 64u * 4u);
  CHECK(full_stats.reflection > 0);
  CHECK(full_stats.refraction > 0);

  CHECK(same_bytes(full, render_all(scene, small_settings(1))));

  // Bands of random heights, rendered in shuffled order by a 2-thread renderer.
  const Renderer r(scene, small_settings(2));
  std::mt19937 rng(42);
  std::vector<std::pair<int, int>> bands;
  for (int y = 0; y < 64;) {
    const int h = std::min(64 - y, 1 + int(rng() % 9));
    bands.push_back({y, y + h});
    y += h;
  }
  std::shuffle(bands.begin(), bands.end(), rng);
  std::vector<float> stitched(full.size());
  RayStats band_stats;
  for (auto [y0, y1] : bands) {
    std::vector<float> band;
    r.render_rows(y0, y1, band, &band_stats);
    REQUIRE(band.size() == size_t(y1 - y0) * 64 * 3);
    std::copy(band.begin(), band.end(), stitched.begin() + size_t(y0) * 64 * 3);
  }
  CHECK(same_bytes(full, stitched));
  CHECK(band_stats.total() == full_stats.total());
  CHECK(band_stats.shadow == full_stats.shadow);

  // The seed does change the jitter.
  RenderSettings other = small_settings(2);
  other.seed = 8;
  CHECK_FALSE(same_bytes(full, render_all(scene, other)));
}

// Spans start pixel groups anywhere: the renderer traces neighbouring
// pixels' grids together (4 pixels' 2x2 grids in one packet), or the
// corners of an adaptive span and of the pixels around it, and a span of one
// pixel traces it alone.
TEST_CASE("render: pixel spans of a row, in any order and on 1 or 2 threads, are the row's bytes") {
  const Scene scene = small_scene();
  for (const bool adaptive : {false, true}) {
    auto settings = [&](int threads) {
      RenderSettings rs = small_settings(threads);
      if (adaptive) rs.spp = 16, rs.adaptive_contrast = 0.1;
      return rs;
    };
    CAPTURE(adaptive);
    RayStats full_stats;
    const std::vector<float> full = render_all(scene, settings(1), &full_stats);
    if (adaptive) {  // every pixel corner, then some pixels' grids, not most
      CHECK(full_stats.eye > 65u * 65u + 64u * 16u);
      CHECK(full_stats.eye < 64u * 64u * 8u);
    }
    std::mt19937 rng(9);
    for (int threads : {1, 2}) {
      const Renderer r(scene, settings(threads));
      std::vector<float> stitched(full.size(), -1.0f);
      RayStats span_stats;
      for (int y = 0; y < 64; ++y) {
        // Spans of random widths, shuffled, 1 to 64 pixels (the whole row too).
        std::vector<std::pair<int, int>> spans;
        for (int x = 0; x < 64;) {
          const int w = std::min(64 - x, 1 + int(rng() % (y % 8 == 0 ? 64 : 20)));
          spans.push_back({x, x + w});
          x += w;
        }
        std::shuffle(spans.begin(), spans.end(), rng);
        for (auto [x0, x1] : spans) {
          std::vector<float> span;
          r.render_span(y, x0, x1, span, &span_stats);
          REQUIRE(span.size() == size_t(x1 - x0) * 3);
          std::copy(span.begin(), span.end(), stitched.begin() + (size_t(y) * 64 + x0) * 3);
        }
      }
      CAPTURE(threads);
      CHECK(same_bytes(full, stitched));
      CHECK(span_stats.total() == full_stats.total());
      CHECK(span_stats.shadow == full_stats.shadow);
    }
  }
}

// Pixels are traced in tiles of rows and columns (8 rows by 512 / (8 k^2)
// columns for uniform grids; refined pixels of adaptive blocks, and grids too
// large to trace whole, in tiles of 8 rows by 64 columns), which need not
// divide the image or the band: a pixel rendered with its tile has the bytes
// of the pixel traced alone.
TEST_CASE("render: an abandoned renderer stops its renders, uniform, adaptive and spans alike") {
  const Scene scene = small_scene();
  for (const bool adaptive : {false, true}) {
    CAPTURE(adaptive);
    RenderSettings rs = small_settings(2);
    if (adaptive) rs.spp = 16, rs.adaptive_contrast = 0.1;
    const Renderer r(scene, rs);
    std::vector<float> rgb;
    r.render_rows(0, 2, rgb);  // renders until abandoned
    r.abandon();
    CHECK_THROWS_AS(r.render_rows(0, rs.height, rgb), RenderAbandoned);
    CHECK_THROWS_AS(r.render_span(3, 5, 9, rgb), RenderAbandoned);
  }
  // From another thread, mid-render: a render of half a minute or more ends at once.
  RenderSettings slow = small_settings(1);
  slow.spp = 4096;
  const Renderer r(scene, slow);
  std::thread stopper([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
    r.abandon();
  });
  const auto start = std::chrono::steady_clock::now();
  std::vector<float> rgb;
  CHECK_THROWS_AS(r.render_rows(0, slow.height, rgb), RenderAbandoned);
  stopper.join();
  CHECK(std::chrono::steady_clock::now() - start < std::chrono::seconds(5));
}

TEST_CASE("render: tiles that do not divide the image are the pixels traced alone") {
  const Scene scene = small_scene();
  for (const test::Sampling sampling : test::kEveryRenderPath) {
    CAPTURE(sampling.spp);
    CAPTURE(sampling.adaptive_contrast);
    RenderSettings rs = small_settings(2);
    rs.width = 37;
    rs.height = 29;
    rs.spp = sampling.spp;
    rs.adaptive_contrast = sampling.adaptive_contrast;
    RayStats full_stats;
    const std::vector<float> full = render_all(scene, rs, &full_stats);
    if (sampling.adaptive_contrast == 0) CHECK(full_stats.eye == uint64_t(37 * 29 * sampling.spp));
    const Renderer r(scene, rs);
    std::vector<float> alone(full.size(), -1.0f);
    for (int y = 0; y < rs.height; ++y) {
      for (int x = 0; x < rs.width; ++x) {
        std::vector<float> pixel;
        r.render_span(y, x, x + 1, pixel);
        std::copy(pixel.begin(), pixel.end(), alone.begin() + (size_t(y) * rs.width + x) * 3);
      }
    }
    CHECK(same_bytes(full, alone));
    // A band that starts and ends inside tiles.
    std::vector<float> band;
    r.render_rows(5, 22, band);
    CHECK(same_bytes(band, std::vector<float>(full.begin() + 5 * 37 * 3, full.begin() + 22 * 37 * 3)));
  }
}

TEST_CASE("render: only the effects a scene calls for are traced") {
  SUBCASE("diffuse only: no reflection or refraction rays") {
    Scene s = small_scene();
    for (Material& m : s.materials) m.ks = m.transmittance = 0;
    // An unused shiny glass material must not switch effects on.
    add_material(s, {1, 1, 1}, 0, 1, 1, 1.5);
    const Renderer r(s, small_settings(2));
    CHECK(r.effects().shadows);
    CHECK_FALSE(r.effects().reflection);
    CHECK_FALSE(r.effects().refraction);
    RayStats st;
    std::vector<float> rgb;
    r.render_rows(0, 64, rgb, &st);
    CHECK(st.reflection == 0);
    CHECK(st.refraction == 0);
    CHECK(st.shadow > 0);
  }
  SUBCASE("no lights: no shadow rays") {
    Scene s = small_scene();
    s.lights.clear();
    const Renderer r(s, small_settings(2));
    CHECK_FALSE(r.effects().shadows);
    CHECK(r.effects().reflection);
    CHECK(r.effects().refraction);
    RayStats st;
    std::vector<float> rgb;
    r.render_rows(0, 64, rgb, &st);
    CHECK(st.shadow == 0);
    CHECK(st.reflection > 0);
  }
  SUBCASE("effect names for the stats") {
    const EffectSet e = derive_effects(small_scene());
    CHECK(e.names() == std::vector<std::string>{"shadows", "reflection", "refraction"});
  }
}

TEST_CASE("render: eye rays at depth 1, max_depth 1 spawns no secondary rays") {
  RenderSettings rs = small_settings(2);
  rs.max_depth = 1;
  RayStats st;
  render_all(small_scene(), rs, &st);
  CHECK(st.reflection == 0);
  CHECK(st.refraction == 0);
  CHECK(st.shadow > 0);
}

TEST_CASE("render: NFF angle spans the centres of the outermost pixels") {
  Camera cam;
  cam.from = {0, 0, 0};
  cam.at = {0, 0, -1};
  cam.up = {0, 1, 0.3};  // not orthogonal: must be orthogonalised
  cam.angle_deg = 45;
  const CameraModel model(cam, 512, 512);
  const double kPi = 3.14159265358979323846;
  auto angle_deg = [&](const Vec3& d) { return std::acos(dot(normalize(d), Vec3{0, 0, -1})) * 180 / kPi; };
  CHECK(angle_deg(model.direction(0.5, 256)) == doctest::Approx(22.5));      // left column centre
  CHECK(angle_deg(model.direction(511.5, 256)) == doctest::Approx(22.5));    // right column centre
  CHECK(angle_deg(model.direction(256, 0.5)) == doctest::Approx(22.5));      // top row centre
  CHECK(model.direction(256, 0.5).y > 0);                                    // row 0 is the top
  CHECK(model.direction(511.5, 256).x > 0);                                  // column 511 is the right
  CHECK(angle_deg(model.direction(256, 256)) == doctest::Approx(0));
}

TEST_CASE("render: pp patches interpolate vertex normals, plain polygons shade flat") {
  auto scene_with = [](bool smooth) {
    Scene s;
    s.camera.from = {0, 0, 5};
    s.camera.at = {0, 0, 0};
    s.camera.up = {0, 1, 0};
    s.lights.push_back({{0, 0, 10}, {1, 1, 1}});
    s.materials.push_back({{1, 1, 1}, 1, 0, 1, 0, 1});
    Polygon p;
    p.count = 3;
    p.has_normals = smooth;
    s.polygons.push_back(p);
    s.vertices = {{-3, -3, 0}, {3, -3, 0}, {0, 3, 0}};
    if (smooth) s.normals = {normalize(Vec3{-1, 0, 1}), normalize(Vec3{1, 0, 1}), Vec3{0, 0, 1}};
    return s;
  };
  RenderSettings rs;
  rs.width = rs.height = 32;
  rs.spp = 1;
  auto pixel = [](const std::vector<float>& rgb, int x, int y) { return rgb[3 * (32 * y + x)]; };
  const std::vector<float> flat = render_all(scene_with(false), rs);
  const std::vector<float> smooth = render_all(scene_with(true), rs);
  // Flat: only the light's distance varies across the triangle.
  CHECK(pixel(flat, 4, 20) == doctest::Approx(pixel(flat, 16, 20)).epsilon(0.01));
  // Smooth: normals tilt outwards towards the left and right corners.
  CHECK(pixel(smooth, 4, 20) < pixel(smooth, 16, 20) - 0.1);
  CHECK(pixel(smooth, 28, 20) < pixel(smooth, 16, 20) - 0.1);
  const Renderer r(scene_with(true), rs);
  CHECK(r.effects().smooth_normals);
}

TEST_CASE("render: settings are validated") {
  const Scene s = small_scene();
  RenderSettings rs = small_settings(1);
  rs.spp = 5;
  CHECK_THROWS_AS(Renderer(s, rs), InputError);
  rs = small_settings(1);
  rs.width = 0;
  CHECK_THROWS_AS(Renderer(s, rs), InputError);
  const Renderer r(s, small_settings(1));
  std::vector<float> rgb;
  CHECK_THROWS_AS(r.render_rows(10, 65, rgb), InputError);
  CHECK_THROWS_AS(r.render_rows(5, 4, rgb), InputError);
  r.render_rows(3, 3, rgb);
  CHECK(rgb.empty());
  CHECK_THROWS_AS(r.render_span(64, 0, 1, rgb), InputError);
  CHECK_THROWS_AS(r.render_span(-1, 0, 1, rgb), InputError);
  CHECK_THROWS_AS(r.render_span(3, 0, 65, rgb), InputError);
  CHECK_THROWS_AS(r.render_span(3, 5, 4, rgb), InputError);
  CHECK_THROWS_AS(r.render_span(3, -1, 4, rgb), InputError);
}

TEST_CASE("render: degenerate geometry never makes a NaN or Inf sample") {
  Scene s = small_scene();
  // A pp patch with a zero vertex normal, a needle cone seen tip-on, a huge and
  // a tiny sphere.
  Polygon p;
  p.first = static_cast<uint32_t>(s.vertices.size());
  p.count = 3;
  p.has_normals = true;
  s.vertices.insert(s.vertices.end(), {{-1, -2, 0.01}, {1, -2, 0.01}, {0, -1, 0.01}});
  s.normals.assign(s.vertices.size(), Vec3{});
  s.polygons.push_back(p);
  s.cones.push_back({{0, -2, 2}, 0.0, {0, 2, 0}, 1e-7, 1});
  s.spheres.push_back({{0, 3, 0}, 1e-12, 2});
  s.spheres.push_back({{0, 0, -1e7}, 1e6, 0});
  RayStats st;
  const std::vector<float> rgb = render_all(s, small_settings(2), &st);
  // The raw count: the image alone would pass anyway, NaN being stored as 0.
  CHECK(st.non_finite == 0);
  CHECK(st.eye > 0);
  CHECK(std::all_of(rgb.begin(), rgb.end(), [](float v) { return std::isfinite(v); }));
}

TEST_CASE("render: a scene translated by 1e6 renders the same (camera-relative BVH)") {
  RenderSettings rs = small_settings(2);
  const std::vector<float> a = render_all(small_scene(), rs);
  const std::vector<float> b = render_all(small_scene(Vec3{1e6, -1e6, 1e6}), rs);
  REQUIRE(a.size() == b.size());
  size_t differ = 0;
  double worst = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    const double d = std::fabs(a[i] - b[i]);
    worst = std::max(worst, d);
    differ += d > 1e-3;
  }
  // Positions are rounded once to double before subtraction, so at most a
  // few edge pixels may pick a different sample neighbour.
  CHECK(differ <= a.size() / 1000);
  CHECK(worst < 1.0);
}

TEST_CASE("render: the cutoff prunes low-weight rays, and only those") {
  const Scene scene = small_scene();
  RenderSettings rs = small_settings(2);
  RayStats full_stats, tiny_stats, pruned_stats;
  const std::vector<float> full = render_all(scene, rs, &full_stats);
  // Every weight in this scene is far above 1e-12: nothing is pruned, and
  // nothing else changes.
  rs.cutoff = 1e-12;
  CHECK(same_bytes(render_all(scene, rs, &tiny_stats), full));
  CHECK(tiny_stats.total() == full_stats.total());

  rs.cutoff = 0.05;
  const std::vector<float> pruned = render_all(scene, rs, &pruned_stats);
  CHECK(pruned_stats.eye == full_stats.eye);
  CHECK(pruned_stats.reflection + pruned_stats.refraction < full_stats.reflection + full_stats.refraction);
  // What is lost is small: each pruned ray could have added at most ~cutoff,
  // plus its own (pruned-weight) subtree.
  double worst = 0, sum = 0;
  for (size_t i = 0; i < full.size(); ++i) {
    worst = std::max(worst, double(std::fabs(full[i] - pruned[i])));
    sum += std::fabs(full[i] - pruned[i]);
  }
  CHECK(worst > 0);
  CHECK(worst < 0.2);
  CHECK(sum / full.size() < 0.01);
}

TEST_CASE("render: the contribution bound is the brightest one hit can shade") {
  // Two lights of intensity 1/sqrt(2); the mirror material (kd 0.4, ks 0.6,
  // colour 0.9 0.9 1) is the brightest: its blue channel reaches
  // 0.2 * 0.4 / sqrt(2) + 2 * (0.4 + 0.6) / sqrt(2).
  const Scene scene = small_scene();
  const EmbreeScene embree(scene, EmbreeOptions{});
  const WhittedIntegrator whitted(scene, embree, small_settings(1));
  CHECK(whitted.contribution_bound() == doctest::Approx((0.2 * 0.4 + 2.0) / std::sqrt(2.0)));
}
