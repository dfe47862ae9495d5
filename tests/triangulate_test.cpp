// Ear-clipping tests: every triangulation must cover exactly the polygon's area
// (shoelace), keep the polygon's winding, and stay inside it (no triangle may
// bridge a gap between gear teeth, which is what a fan would do).
#include <doctest/doctest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <random>
#include <set>
#include <vector>

#include "tests/test_paths.h"
#include "tracer/nff_reader.h"
#include "tracer/triangle_pieces.h"
#include "tracer/triangulate.h"

using namespace rayfarm;

namespace {

struct P2 {
  double x, y;
};

double shoelace(const std::vector<P2>& p) {
  double a = 0;
  for (size_t i = 0; i < p.size(); ++i) {
    const P2& u = p[i];
    const P2& v = p[(i + 1) % p.size()];
    a += u.x * v.y - v.x * u.y;
  }
  return 0.5 * a;
}

// Even-odd rule (Haines, "Point in Polygon Strategies", Graphics Gems IV).
bool inside(const std::vector<P2>& p, P2 q) {
  bool in = false;
  for (size_t i = 0, j = p.size() - 1; i < p.size(); j = i++) {
    if ((p[i].y > q.y) != (p[j].y > q.y) &&
        q.x < (p[j].x - p[i].x) * (q.y - p[i].y) / (p[j].y - p[i].y) + p[i].x)
      in = !in;
  }
  return in;
}

// Places 2-D outlines in a tilted plane so the dominant-axis projection is
// exercised, not just the z = 0 case.
std::vector<Vec3> embed(const std::vector<P2>& p) {
  const Vec3 origin{0.3, -1.2, 2.0};
  const Vec3 e1 = normalize(Vec3{1, 0.2, 0.5});
  const Vec3 e2 = normalize(cross(Vec3{0.1, -0.4, 1}, e1));
  std::vector<Vec3> out;
  for (const P2& q : p) out.push_back(origin + q.x * e1 + q.y * e2);
  return out;
}

// Checks the triangulation of `outline` and returns the triangle count.
size_t check_triangulation(const std::vector<P2>& outline) {
  const std::vector<Vec3> v = embed(outline);
  const std::vector<uint32_t> idx = triangulate_polygon(v.data(), static_cast<uint32_t>(v.size()));
  REQUIRE(idx.size() % 3 == 0);
  const Vec3 normal = normalize(polygon_normal(v.data(), static_cast<uint32_t>(v.size())));
  double area = 0;
  for (size_t t = 0; t < idx.size(); t += 3) {
    for (int k = 0; k < 3; ++k) REQUIRE(idx[t + k] < v.size());
    const Vec3 n = cross(v[idx[t + 1]] - v[idx[t]], v[idx[t + 2]] - v[idx[t]]);
    CHECK(dot(n, normal) > 0);  // wound like the polygon, and not degenerate
    area += 0.5 * length(n);
    const P2 c{(outline[idx[t]].x + outline[idx[t + 1]].x + outline[idx[t + 2]].x) / 3,
               (outline[idx[t]].y + outline[idx[t + 1]].y + outline[idx[t + 2]].y) / 3};
    CHECK(inside(outline, c));
  }
  CHECK(area == doctest::Approx(std::abs(shoelace(outline))).epsilon(1e-9));
  return idx.size() / 3;
}

std::vector<P2> reversed(std::vector<P2> p) { return {p.rbegin(), p.rend()}; }

// Both windings of the same outline.
size_t check_both_windings(const std::vector<P2>& outline) {
  const size_t n = check_triangulation(outline);
  CHECK(check_triangulation(reversed(outline)) == n);
  return n;
}

// A gear outline as the SPD gears generator builds it: 36 teeth, 4 points per
// tooth, tips at radius 0.995 and roots at 0.9.
std::vector<P2> gear_outline(double offset, double direction) {
  const double tooth = direction * 2 * M_PI / 36;
  std::vector<P2> p;
  for (int k = 0; k < 36; ++k) {
    const double a = offset + k * tooth;
    for (auto [r, da] : {std::pair{0.995, -0.19}, {0.995, 0.19}, {0.9, 0.3}, {0.9, 0.7}})
      p.push_back({r * std::cos(a + da * tooth), r * std::sin(a + da * tooth)});
  }
  return p;
}

std::vector<P2> star(int points, double outer, double inner) {
  std::vector<P2> p;
  for (int i = 0; i < 2 * points; ++i) {
    const double r = i % 2 ? inner : outer;
    const double a = M_PI * i / points;
    p.push_back({r * std::cos(a), r * std::sin(a)});
  }
  return p;
}

}  // namespace

TEST_CASE("triangulate: triangle") {
  CHECK(check_both_windings({{0, 0}, {1, 0}, {0, 1}}) == 1);
}

TEST_CASE("triangulate: convex quad") {
  CHECK(check_both_windings({{0, 0}, {2, 0}, {2, 1}, {0, 1}}) == 2);
}

TEST_CASE("triangulate: concave quad (dart)") {
  CHECK(check_both_windings({{0, 0}, {2, 1}, {0, 2}, {0.5, 1}}) == 2);
}

TEST_CASE("triangulate: concave L shape") {
  CHECK(check_both_windings({{0, 0}, {3, 0}, {3, 1}, {1, 1}, {1, 2}, {0, 2}}) == 4);
}

TEST_CASE("triangulate: five-pointed star") {
  CHECK(check_both_windings(star(5, 1.0, 0.38)) == 8);
}

TEST_CASE("triangulate: 36-tooth gear outline like the SPD gears") {
  CHECK(check_both_windings(gear_outline(0, 1)) == 142);
  CHECK(check_both_windings(gear_outline(M_PI / 36, -1)) == 142);
}

TEST_CASE("triangulate: a gear's face becomes triangles that fill their boxes") {
  // Flat in z, as the SPD gears lie: a triangle's box is its 2-D box. Cutting
  // the next ear met fanned this outline into slivers (the worst box 95 times
  // its triangle, the boxes together 8 times the face's area, both faces);
  // the best ear first leaves none that triangle_pieces.h would cut, and
  // boxes about twice the face's area.
  for (const std::vector<P2>& outline : {gear_outline(0, 1), gear_outline(M_PI / 36, -1)}) {
    std::vector<Vec3> v;
    for (const P2& q : outline) v.push_back({q.x, q.y, 0});
    const std::vector<uint32_t> idx = triangulate_polygon(v.data(), static_cast<uint32_t>(v.size()));
    REQUIRE(idx.size() == 3 * 142);
    double box_area = 0;
    for (size_t t = 0; t < idx.size(); t += 3) {
      const Vec3 &a = v[idx[t]], &b = v[idx[t + 1]], &c = v[idx[t + 2]];
      CHECK(triangle_piece_count(a, b, c) == 1);
      const Box box = box_of({a, b, c});
      box_area += (box.hi.x - box.lo.x) * (box.hi.y - box.lo.y);
    }
    CHECK(box_area < 2.5 * std::abs(shoelace(outline)));
  }
}

TEST_CASE("triangulate: collinear vertices add no slivers") {
  // Unit square with extra points on three edges.
  const std::vector<P2> square{{0, 0}, {0.5, 0}, {1, 0}, {1, 0.25}, {1, 1}, {0.5, 1}, {0, 1}};
  for (const auto& outline : {square, reversed(square)}) {
    const size_t n = check_triangulation(outline);
    CHECK(n >= 2);
    CHECK(n <= 5);
  }
}

TEST_CASE("triangulate: repeated vertices") {
  CHECK(check_both_windings({{0, 0}, {0, 0}, {1, 0}, {1, 1}, {1, 1}, {0, 1}, {0, 0}}) == 2);
  // Two squares touching at a corner: the outline visits (1, 1) twice.
  CHECK(check_both_windings({{0, 0}, {1, 0}, {1, 1}, {2, 1}, {2, 2}, {1, 2}, {1, 1}, {0, 1}}) == 4);
}

TEST_CASE("triangulate: degenerate input gives no triangles") {
  const std::vector<Vec3> line{{0, 0, 0}, {1, 1, 1}, {2, 2, 2}, {3, 3, 3}};
  CHECK(triangulate_polygon(line.data(), 4).empty());
  const std::vector<Vec3> point{{1, 2, 3}, {1, 2, 3}, {1, 2, 3}};
  CHECK(triangulate_polygon(point.data(), 3).empty());
  CHECK(triangulate_polygon(point.data(), 2).empty());
  CHECK(triangulate_polygon(nullptr, 0).empty());
  const std::vector<Vec3> nan{{0, 0, 0}, {1, 0, 0}, {0, NAN, 0}, {0, 1, 0}};
  CHECK(triangulate_polygon(nan.data(), 4).empty());
}

TEST_CASE("triangulate: self-intersecting input terminates") {
  // A bow tie is not simple: any answer is acceptable as long as it ends and
  // only indexes real vertices.
  const std::vector<Vec3> bow{{0, 0, 0}, {2, 2, 0}, {2, 0, 0}, {0, 2, 0}, {1, 3, 0}};
  const std::vector<uint32_t> idx = triangulate_polygon(bow.data(), 5);
  CHECK(idx.size() <= 9);
  for (uint32_t i : idx) CHECK(i < 5);
}

TEST_CASE("triangulate: polygons with no ear left terminate") {
  // Random vertex rings cross themselves; on these, a cut can leave no ear
  // among the cached ones (the clipper looks at every vertex again and
  // finds one: 45 times here) or none at all (it cuts the most convex
  // corner: 116 times, the heptagram among them). Any answer will do that ends, indexes real
  // vertices, has at most n - 2 triangles and no triangle twice.
  std::vector<std::vector<Vec3>> rings;
  std::vector<Vec3> heptagram;  // a star drawn in one stroke: every corner is crossed
  for (int i = 0; i < 7; ++i) {
    const double a = 2 * M_PI * ((3 * i) % 7) / 7;
    heptagram.push_back({std::cos(a), std::sin(a), 0});
  }
  rings.push_back(heptagram);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int t = 0; t < 200; ++t) {
    std::vector<Vec3> v;
    for (int i = 0; i < 8; ++i) v.push_back({u(rng), u(rng), 0});
    rings.push_back(v);
  }
  for (const std::vector<Vec3>& v : rings) {
    const std::vector<uint32_t> idx = triangulate_polygon(v.data(), static_cast<uint32_t>(v.size()));
    CHECK(idx.size() % 3 == 0);
    CHECK(idx.size() <= 3 * (v.size() - 2));
    for (uint32_t i : idx) CHECK(i < v.size());
    std::set<std::array<uint32_t, 3>> seen;
    for (size_t t = 0; t + 2 < idx.size(); t += 3) {
      std::array<uint32_t, 3> tri{idx[t], idx[t + 1], idx[t + 2]};
      std::sort(tri.begin(), tri.end());
      CHECK(seen.insert(tri).second);
    }
  }
}

TEST_CASE("triangulate: random star-shaped polygons (fixed seed)") {
  // Jittered angles (consecutive gaps below pi) and random radii give simple
  // polygons that are star-shaped around the origin, mostly concave.
  std::mt19937 rng(1234);
  std::uniform_real_distribution<double> unit(0, 1);
  for (int trial = 0; trial < 200; ++trial) {
    const int n = 3 + trial % 40;
    std::vector<P2> p;
    for (int i = 0; i < n; ++i) {
      const double a = 2 * M_PI * (i + 0.45 * unit(rng)) / n;
      const double r = 0.2 + unit(rng);
      p.push_back({r * std::cos(a), r * std::sin(a)});
    }
    CAPTURE(trial);
    check_triangulation(trial % 2 ? reversed(p) : p);
  }
}

TEST_CASE("triangulate: every polygon of the gears-2 reference scene") {
  const Scene scene = read_nff_file(test::spd_data("gears-2"));
  size_t big = 0;
  for (const Polygon& poly : scene.polygons) {
    const Vec3* v = &scene.vertices[poly.first];
    const std::vector<uint32_t> idx = triangulate_polygon(v, poly.count);
    REQUIRE(idx.size() == 3 * (poly.count - 2));
    const Vec3 normal = polygon_normal(v, poly.count);
    double area = 0;
    for (size_t t = 0; t < idx.size(); t += 3) {
      const Vec3 n = cross(v[idx[t + 1]] - v[idx[t]], v[idx[t + 2]] - v[idx[t]]);
      CHECK(dot(n, normal) > 0);
      area += length(n);
    }
    CHECK(area == doctest::Approx(length(normal)).epsilon(1e-6));
    big += poly.count == 144;
  }
  CHECK(big == 16);
}
