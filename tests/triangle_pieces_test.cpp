// Triangle pieces: together they must hold every point of their triangle --
// a point outside all of them is a hit the BVH never offers -- and they pay
// only for slivers: a triangle that fills its box stays whole, a diagonal
// sliver's pieces enclose far less space than its box.
#include <doctest/doctest.h>

#include <random>
#include <vector>

#include "tracer/triangle_pieces.h"

using namespace rayfarm;

namespace {

bool inside(const Box& b, const Vec3& p) {
  return p.x >= b.lo.x && p.x <= b.hi.x && p.y >= b.lo.y && p.y <= b.hi.y && p.z >= b.lo.z && p.z <= b.hi.z;
}

bool covered(const std::vector<Box>& pieces, const Vec3& p) {
  for (const Box& b : pieces) {
    if (inside(b, p)) return true;
  }
  return false;
}

// The area a box covers in the x-y plane.
double footprint(const Box& b) {
  const Vec3 e = b.hi - b.lo;
  return e.x * e.y;
}

}  // namespace

TEST_CASE("triangle pieces: every point of random triangles and slivers lies in a piece") {
  std::mt19937_64 rng(20261129);
  std::uniform_real_distribution<double> coord(-100, 100), unit(0, 1);
  for (int n = 0; n < 2000; ++n) {
    const Vec3 a{coord(rng), coord(rng), coord(rng)};
    Vec3 b{coord(rng), coord(rng), coord(rng)};
    // Every other triangle a sliver: c close to the segment ab.
    Vec3 c = n % 2 ? a + unit(rng) * (b - a) + Vec3{1e-3, -2e-3, 1e-3} * unit(rng)
                   : Vec3{coord(rng), coord(rng), coord(rng)};
    const int count = triangle_piece_count(a, b, c);
    REQUIRE(count >= 1);
    REQUIRE(count <= kMaxTrianglePieces);
    const std::vector<Box> pieces = triangle_pieces(a, b, c, count);
    CHECK(pieces.size() == size_t(count));
    for (const Vec3& v : {a, b, c}) CHECK(covered(pieces, v));
    for (int k = 0; k < 200; ++k) {
      double u = unit(rng), v = unit(rng);
      if (u + v > 1) u = 1 - u, v = 1 - v;
      const Vec3 p = a + u * (b - a) + v * (c - a);
      CAPTURE(n);
      CAPTURE(k);
      REQUIRE(covered(pieces, p));
    }
  }
}

TEST_CASE("triangle pieces: compact triangles stay whole, diagonal slivers are split into tight pieces") {
  // A right triangle filling half of a flat box.
  CHECK(triangle_piece_count({0, 0, 0}, {1, 0, 0}, {0, 1, 0}) == 1);
  // A facet tilted against every axis, its box surface 8.2 times its area,
  // stays whole too: it is no sliver, and a ray through two pieces would
  // test it twice (it was cut into three before).
  CHECK(triangle_piece_count({0, 0, 0}, {1, 0, 0.6}, {0.3, 1, 0.9}) == 1);
  // Degenerate triangles stay whole (their box is all there is).
  CHECK(triangle_piece_count({0, 0, 0}, {1, 1, 1}, {2, 2, 2}) == 1);
  CHECK(triangle_pieces({0, 0, 0}, {1, 1, 1}, {2, 2, 2}, 1).size() == 1);
  // A sliver 10 long and 0.05 wide across the x-y diagonal.
  const Vec3 a{0, 0, 0}, b{10, 10, 0}, c{5.05, 4.95, 0};
  const int count = triangle_piece_count(a, b, c);
  CHECK(count == kMaxTrianglePieces);
  const std::vector<Box> pieces = triangle_pieces(a, b, c, count);
  double sum = 0;
  for (const Box& p : pieces) sum += footprint(p);
  const Box whole = triangle_pieces(a, b, c, 1).front();
  CHECK(sum < 0.1 * footprint(whole));
}

TEST_CASE("triangle pieces: appending keeps what the vector held and counts what it added") {
  const Vec3 a{0, 0, 0}, b{10, 10, 0.1}, c{10.2, 10, 0};
  const int count = triangle_piece_count(a, b, c);
  REQUIRE(count > 1);
  std::vector<Box> boxes{{{-1, -1, -1}, {1, 1, 1}}};
  const int added = append_triangle_pieces(a, b, c, count, boxes);
  const std::vector<Box> alone = triangle_pieces(a, b, c, count);
  CHECK(added == static_cast<int>(alone.size()));
  REQUIRE(boxes.size() == alone.size() + 1);
  CHECK(boxes[0].lo.x == -1);
  for (size_t i = 0; i < alone.size(); ++i) {
    CHECK(boxes[i + 1].lo.x == alone[i].lo.x);
    CHECK(boxes[i + 1].hi.y == alone[i].hi.y);
  }
}

TEST_CASE("triangle pieces: a quad's halves pair, neighbours side by side and distant triangles do not") {
  auto pair = [](const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d, const Vec3& e, const Vec3& f) {
    return worth_pairing(box_of({a, b, c, d, e, f}), box_of({a, b, c}), box_of({d, e, f}));
  };
  // A square's two halves: each box is the whole square's.
  CHECK(pair({0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 0, 0}, {1, 1, 0}, {0, 1, 0}));
  // Two facets of a mesh across the diagonal of a bent (non-planar) quad.
  CHECK(pair({0, 0, 0}, {1, 0, 0.1}, {1, 1, 0.3}, {0, 0, 0}, {1, 1, 0.3}, {0, 1, 0.2}));
  // Two facets sharing an edge side by side: the joint box is twice each.
  CHECK_FALSE(pair({0, 0, 0}, {1, 0, 0}, {0.5, 0.9, 0}, {0, 0, 0}, {1, 0, 0}, {0.5, -0.8, 0.1}));
  // The same triangle twice, far apart: the joint box is mostly empty.
  CHECK_FALSE(pair({0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {5, 5, 0}, {6, 5, 0}, {5, 6, 0}));
  // Side by side, touching at a corner only.
  CHECK_FALSE(pair({0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 1}, {2, 1, 1}, {1, 2, 1}));
}
