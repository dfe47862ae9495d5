// ScreenFootprint: the pixels through which an eye ray may meet the scene's
// box, or one of the hulls around its primitives, are all kept (no ray
// through a ruled-out pixel meets them), their surroundings are ruled out,
// and a render that skips the ruled-out pixels has the bytes and ray counts
// of one that traces them.
#include <doctest/doctest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

#include "tracer/box.h"
#include "tracer/camera.h"
#include "tracer/embree_scene.h"
#include "tracer/renderer.h"
#include "tracer/screen_footprint.h"
#include "tracer/shapes.h"
#include "tests/render_paths.h"

using namespace rayfarm;
using rayfarm::test::same_bytes;

namespace {

// Whether the ray from the origin along d meets the box [lo, hi] (t > 0).
bool ray_meets_box(const Vec3& d, const Vec3& lo, const Vec3& hi) {
  double t0 = 0, t1 = HUGE_VAL;
  for (int a = 0; a < 3; ++a) {
    if (d[a] == 0) {
      if (lo[a] > 0 || hi[a] < 0) return false;
      continue;
    }
    double ta = lo[a] / d[a], tb = hi[a] / d[a];
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta), t1 = std::min(t1, tb);
  }
  return t0 <= t1;
}

Camera looking_at(const Vec3& from, const Vec3& at) {
  Camera c;
  c.from = from;
  c.at = at;
  c.up = {0, 0, 1};
  c.angle_deg = 40;
  return c;
}

// A cube of six polygons off the image's centre, seen corner-on, with a
// sphere beside it and a tilted tube across the image, against the
// background: the box's image holds much background between them that only
// the primitives' hulls rule out, and the cube's silhouette runs along the
// rectangles around its faces' images.
Scene cube_scene() {
  Scene s;
  s.background = {0.3, 0.1, 0.5};
  s.camera = looking_at({5, -6, 4}, {0.6, 0.3, 0.2});
  s.lights.push_back({Vec3{4, -3, 6}, {1, 1, 1}});
  s.materials.push_back({{0.9, 0.7, 0.3}, 0.7, 0.3, 20.0, 0, 1});
  const Vec3 v[8] = {{-1, -1, -1}, {1, -1, -1}, {1, 1, -1}, {-1, 1, -1},
                     {-1, -1, 1},  {1, -1, 1},  {1, 1, 1},  {-1, 1, 1}};
  const int faces[6][4] = {{0, 3, 2, 1}, {4, 5, 6, 7}, {0, 1, 5, 4}, {2, 3, 7, 6}, {1, 2, 6, 5}, {0, 4, 7, 3}};
  for (const auto& f : faces) {
    Polygon p;
    p.first = static_cast<uint32_t>(s.vertices.size());
    p.count = 4;
    p.material = 0;
    for (int i : f) s.vertices.push_back(v[i]);
    s.polygons.push_back(p);
  }
  s.spheres.push_back({Vec3{0.2, -1.6, 0.4}, 0.5, 0});
  s.cones.push_back({Vec3{-3.5, 2.5, -1.5}, 0.15, Vec3{-1.5, 4.5, 0.8}, 0.15, 0});
  return s;
}

// Whether the ray from the origin along d meets the convex hull of
// `points`: a box's eight corners, or a triangle's three.
bool ray_meets_hull(const Vec3& d, const std::vector<Vec3>& points) {
  if (points.size() == 3) {
    TriangleHit hit;
    return intersect_triangle(ShearedRay({0, 0, 0}, d), points[0], points[1], points[2], 0, HUGE_VAL, hit);
  }
  return ray_meets_box(d, points[0], points[7]);
}

std::vector<Vec3> corners(const Vec3& lo, const Vec3& hi) {
  const std::array<Vec3, 8> c = box_corners({lo, hi});
  return {c.begin(), c.end()};
}

}  // namespace

TEST_CASE("screen footprint: no ray through a ruled-out pixel meets the box, and the box's surroundings are ruled out") {
  const int width = 64, height = 48;
  const Camera camera = looking_at({4, -7, 3}, {1.5, 0, 1});
  const CameraModel model(camera, width, height);
  const Vec3 lo = Vec3{-1, -1, -1} - camera.from, hi = Vec3{1, 1, 1} - camera.from;
  const ScreenFootprint footprint(model, width, height, lo, hi);
  long missing_everywhere = 0;
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      bool meets = false;  // some ray through the pixel's square, edges included
      for (int a = 0; a <= 8; ++a) {
        for (int b = 0; b <= 8; ++b) meets |= ray_meets_box(model.direction(x + a / 8.0, y + b / 8.0), lo, hi);
      }
      if (meets) CHECK(footprint.pixel(x, y));
      missing_everywhere += !meets;
    }
  }
  // The margin keeps two pixels around the box's image: most of the rest goes.
  CHECK(footprint.ruled_out() > 0);
  CHECK(footprint.ruled_out() <= missing_everywhere);
  CHECK(footprint.ruled_out() >= missing_everywhere * 3 / 4);
  // A lattice corner may be seen when a pixel that shares it may, and a
  // pixel's neighbourhood when a pixel within its reach may.
  const auto any_pixel = [&](int x0, int x1, int y0, int y1) {
    bool any = false;
    for (int y = std::max(0, y0); y <= std::min(height - 1, y1); ++y) {
      for (int x = std::max(0, x0); x <= std::min(width - 1, x1); ++x) any |= footprint.pixel(x, y);
    }
    return any;
  };
  for (int j = 0; j <= height; ++j) {
    for (int i = 0; i <= width; ++i) CHECK(footprint.corner(i, j) == any_pixel(i - 1, i, j - 1, j));
  }
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      CHECK(footprint.near(x, y, 2) == any_pixel(x - 2, x + 2, y - 2, y + 2));
      CHECK(footprint.near(x, y, 0) == footprint.pixel(x, y));
    }
  }
}

TEST_CASE("screen footprint: a box behind the eye rules out every pixel, one across the eye's plane, or empty, none") {
  const int width = 20, height = 10;
  const Camera camera = looking_at({0, 0, 0}, {0, 1, 0});
  const CameraModel model(camera, width, height);
  CHECK(ScreenFootprint(model, width, height, {-1, -5, -1}, {1, -3, 1}).ruled_out() == width * height);
  CHECK(ScreenFootprint(model, width, height, {-1, -5, -1}, {1, 0, 1}).ruled_out() == width * height);
  CHECK(ScreenFootprint(model, width, height, {-1, -5, -1}, {1, 3, 1}).ruled_out() == 0);
  CHECK(ScreenFootprint(model, width, height, {1, 1, 1}, {-1, 2, -1}).ruled_out() == 0);
  CHECK(ScreenFootprint(width, height).ruled_out() == 0);
}

TEST_CASE("screen footprint: skipping the ruled-out pixels changes no byte and no ray count") {
  const Scene scene = cube_scene();
  for (const test::Sampling sampling : test::kEveryRenderPath) {
    CAPTURE(sampling.spp);
    CAPTURE(sampling.adaptive_contrast);
    RenderSettings rs;
    rs.width = 45;
    rs.height = 33;
    rs.spp = sampling.spp;
    rs.adaptive_contrast = sampling.adaptive_contrast;
    rs.threads = 2;
    Renderer::Options tracing_all;
    tracing_all.skip_unseen_pixels = false;
    const Renderer skipping(scene, rs), tracing(scene, rs, tracing_all);
    std::vector<float> a, b;
    RayStats sa, sb;
    skipping.render_rows(0, rs.height, a, &sa);
    tracing.render_rows(0, rs.height, b, &sb);
    CHECK(same_bytes(a, b));
    CHECK(sa.eye == sb.eye);
    CHECK(sa.eye_hit == sb.eye_hit);
    CHECK(sa.shadow == sb.shadow);
    CHECK(sa.reflection == sb.reflection);
    CHECK(sa.refraction == sb.refraction);
    CHECK(sa.non_finite == sb.non_finite);
    // A band, and a span, that start and end inside tiles.
    skipping.render_rows(7, 26, a);
    tracing.render_rows(7, 26, b);
    CHECK(same_bytes(a, b));
    skipping.render_span(3, 2, 41, a);
    tracing.render_span(3, 2, 41, b);
    CHECK(same_bytes(a, b));
  }
  // And pixels were skipped, as the renderer finds them: the box leaves
  // much of the image to the background, and the hulls more.
  const EmbreeScene embree(scene, EmbreeOptions{});
  Vec3 lo, hi;
  embree.bounds(lo, hi);
  const CameraModel model(scene.camera, 45, 33);
  ScreenFootprint footprint(model, 45, 33, lo, hi);
  const long by_box = footprint.ruled_out();
  footprint.narrow_to_hulls(model, [&](const auto& visit) { embree.for_each_hull(visit); });
  CHECK(by_box > 45 * 33 / 10);
  CHECK(footprint.ruled_out() > by_box + 45 * 33 / 10);
}

TEST_CASE("screen footprint: narrowed to hulls, no ray through a ruled-out pixel meets one, most others ruled out") {
  const int width = 64, height = 48;
  const Camera camera = looking_at({4, -7, 3}, {1.5, 0, 1});
  const CameraModel model(camera, width, height);
  const Vec3 eye = camera.from;
  // Two boxes apart and a triangle, camera-relative.
  const std::vector<std::vector<Vec3>> hulls = {
      corners(Vec3{-1, -1, -1} - eye, Vec3{-0.5, 0, 0} - eye),
      corners(Vec3{2, 1, 1.5} - eye, Vec3{2.6, 1.4, 2.2} - eye),
      {Vec3{3, 0, -1} - eye, Vec3{4, 0.5, -1} - eye, Vec3{3.2, 0.2, 0} - eye},
  };
  ScreenFootprint footprint(width, height);
  footprint.narrow_to_hulls(model, [&](const auto& visit) {
    for (const std::vector<Vec3>& h : hulls) {
      if (!visit(h.data(), static_cast<int>(h.size()))) return;
    }
  });
  long missing_everywhere = 0;
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      bool meets = false;  // some ray through the pixel's square, edges included, meets some hull
      for (int a = 0; a <= 8; ++a) {
        for (int b = 0; b <= 8; ++b) {
          const Vec3 d = model.direction(x + a / 8.0, y + b / 8.0);
          for (const std::vector<Vec3>& h : hulls) meets |= ray_meets_hull(d, h);
        }
      }
      if (meets) CHECK(footprint.pixel(x, y));
      missing_everywhere += !meets;
    }
  }
  CHECK(footprint.ruled_out() <= missing_everywhere);
  CHECK(footprint.ruled_out() >= missing_everywhere * 3 / 4);
}

TEST_CASE("screen footprint: a hull behind the eye adds no pixel, one across the eye's plane every pixel") {
  const int width = 20, height = 10;
  const CameraModel model(looking_at({0, 0, 0}, {0, 1, 0}), width, height);
  const std::vector<Vec3> behind = corners({-1, -5, -1}, {1, -3, 1});
  const std::vector<Vec3> across = corners({-1, -5, -1}, {1, 3, 1});
  const std::vector<Vec3> ahead = {{0, 5, 0}, {0.1, 5, 0}, {0, 5, 0.1}};
  ScreenFootprint hulls = ScreenFootprint::none(width, height);
  CHECK(hulls.ruled_out() == width * height);
  hulls.add_hull(model, behind.data(), 8);
  CHECK(hulls.ruled_out() == width * height);
  hulls.add_hull(model, ahead.data(), 3);
  CHECK(hulls.ruled_out() > 0);
  CHECK(hulls.ruled_out() < width * height);
  hulls.add_hull(model, across.data(), 8);
  CHECK(hulls.ruled_out() == 0);
  CHECK(hulls.keeps_all_of(ScreenFootprint(width, height)));
  // Once the hulls keep every pixel the footprint keeps, no more are asked for.
  ScreenFootprint footprint(width, height);
  long asked = 0;
  footprint.narrow_to_hulls(model, [&](const auto& visit) {
    while (asked < 10 * ScreenFootprint::kHullsBetweenChecks && visit(across.data(), 8)) ++asked;
  });
  CHECK(asked == ScreenFootprint::kHullsBetweenChecks - 1);
  CHECK(footprint.ruled_out() == 0);
}

TEST_CASE("screen footprint: a huge image's keeps blocks of pixels, and every pixel a ray of which meets the box") {
  CHECK(ScreenFootprint(4096, 4096).block_side() == 1);
  CHECK(ScreenFootprint(4097, 4096).block_side() == 2);
  CHECK(ScreenFootprint(65536, 65536).block_side() == 16);
  CHECK(ScreenFootprint(65536, 65536).ruled_out() == 0);
  CHECK(ScreenFootprint(8191, 6007).ruled_out() == 0);  // the last column and row of blocks cut short
  CHECK(ScreenFootprint::none(65536, 65533).ruled_out() == 65536L * 65533);
  const int width = 8191, height = 6007;  // blocks of 2 x 2, the last column and row of them cut short
  const Camera camera = looking_at({4, -7, 3}, {1.5, 0, 1});
  const CameraModel model(camera, width, height);
  const Vec3 lo = Vec3{-1, -1, -1} - camera.from, hi = Vec3{1, 1, 1} - camera.from;
  ScreenFootprint footprint(model, width, height, lo, hi);
  REQUIRE(footprint.block_side() == 2);
  const long by_box = footprint.ruled_out();
  const std::vector<Vec3> box = corners(lo, hi);
  footprint.narrow_to_hulls(model, [&](const auto& visit) { visit(box.data(), 8); });
  CHECK(footprint.ruled_out() == by_box);  // the box is the only hull
  CHECK(by_box > long(width) * height / 4);
  CHECK(by_box < long(width) * height);
  long counted = 0;  // ruled_out() counts the pixels of the blocks, the last column's and row's cut short
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) counted += !footprint.pixel(x, y);
  }
  CHECK(counted == by_box);
  for (int y = 0; y < height; y += 31) {
    for (int x = 0; x < width; x += 37) {
      bool meets = false;
      for (int a = 0; a <= 2; ++a) {
        for (int b = 0; b <= 2; ++b) meets |= ray_meets_box(model.direction(x + a / 2.0, y + b / 2.0), lo, hi);
      }
      if (meets) CHECK(footprint.pixel(x, y));
      // A block is kept or ruled out whole.
      CHECK(footprint.pixel(x, y) == footprint.pixel(x ^ 1, std::min(y ^ 1, height - 1)));
      CHECK(footprint.near(x, y, 0) == footprint.pixel(x, y));
    }
  }
}
