// Slab pieces of a triangle (see the header).
#include "tracer/triangle_pieces.h"

#include <algorithm>
#include <cmath>

namespace rayfarm {

namespace {

int longest_axis(const Vec3& e) { return e.x >= e.y ? (e.x >= e.z ? 0 : 2) : (e.y >= e.z ? 1 : 2); }

double coordinate(const Vec3& v, int axis) { return axis == 0 ? v.x : axis == 1 ? v.y : v.z; }

double surface(const Box& box) {
  const Vec3 e = box.hi - box.lo;
  return 2 * (e.x * e.y + e.y * e.z + e.z * e.x);
}

}  // namespace

bool worth_pairing(const Box& both, const Box& a, const Box& b) {
  // Neighbours in the scene file's order: on mount (3,519 pairs of its
  // 8,192 facets) 0.97x the time of single triangles, tetra (2,048 pairs of
  // 4,096) 0.96x, gears (12,385 pairs, its 9,216 side quads among them)
  // 0.98x the time of pairing quads alone; a ratio of 0.6 paired fewer
  // (mount 2,401) for no more gain. Gears' faces, cut into triangles that
  // fill their boxes (triangulate.cpp), pair too: 15,337 pairs, and 0.6 or
  // 0.9 took the same time as 0.75, no pairing 1.12x.
  return surface(both) <= kPairedSurfaceRatio * (surface(a) + surface(b));
}

double box_emptiness(const Vec3& a, const Vec3& b, const Vec3& c) {
  const double area = 0.5 * length(cross(b - a, c - a));
  return area > 0 ? surface(box_of({a, b, c})) / area : HUGE_VAL;
}

int triangle_piece_count(const Vec3& a, const Vec3& b, const Vec3& c) {
  // box_emptiness(): a sliver takes one piece per 4 of that
  // ratio: on gears (512x512, 16 spp, one thread) 1.28x faster than no pieces,
  // where one per 16 gained 1.06x and one per 3 (up to 32 pieces) another 4%.
  // But every piece tests the whole triangle, so a ray through the boxes of
  // two pieces tests it twice: a triangle below kWholeTriangleRatio stays
  // whole. Tilted facets of a mesh reach ratios of 4 to 12 without being
  // slivers: mount's, 2.7 pieces each, rendered 1.05x slower than whole and
  // built 2.4x slower.
  const double ratio = box_emptiness(a, b, c);  // no area, or no finite box: one piece
  if (!std::isfinite(ratio) || !(ratio >= kWholeTriangleRatio)) return 1;
  const double pieces = std::ceil(ratio / 4);
  return pieces >= kMaxTrianglePieces ? kMaxTrianglePieces : static_cast<int>(pieces);
}

std::vector<Box> triangle_pieces(const Vec3& a, const Vec3& b, const Vec3& c, int count) {
  std::vector<Box> pieces;
  append_triangle_pieces(a, b, c, count, pieces);
  return pieces;
}

int append_triangle_pieces(const Vec3& a, const Vec3& b, const Vec3& c, int count, std::vector<Box>& out) {
  const Box whole = box_of({a, b, c});
  if (count <= 1) {
    out.push_back(whole);
    return 1;
  }
  const int axis = longest_axis(whole.hi - whole.lo);
  const double lo = coordinate(whole.lo, axis), hi = coordinate(whole.hi, axis);
  const Vec3 v[3] = {a, b, c};
  // Rounding in the edge/plane points below is ~1e-16 of the triangle's size;
  // the pad (1e-9 of it) keeps every piece a superset of its exact part.
  const Vec3 size = whole.hi - whole.lo;
  const double pad = 1e-9 * std::max({size.x, size.y, size.z});
  const size_t first = out.size();
  for (int i = 0; i < count; ++i) {
    // The first and last slabs end at the triangle's own extremes exactly.
    const double s0 = i == 0 ? lo : lo + (hi - lo) * i / count;
    const double s1 = i == count - 1 ? hi : lo + (hi - lo) * (i + 1) / count;
    // The part's vertices: the triangle's vertices inside the slab, and where
    // its edges cross the slab's two planes.
    Box part{{HUGE_VAL, HUGE_VAL, HUGE_VAL}, {-HUGE_VAL, -HUGE_VAL, -HUGE_VAL}};
    for (int k = 0; k < 3; ++k) {
      const Vec3& p = v[k];
      const Vec3& q = v[(k + 1) % 3];
      const double pk = coordinate(p, axis), qk = coordinate(q, axis);
      if (pk >= s0 && pk <= s1) grow(part, p);
      for (const double s : {s0, s1}) {
        if ((pk < s && qk > s) || (pk > s && qk < s)) grow(part, p + ((s - pk) / (qk - pk)) * (q - p));
      }
    }
    if (!(part.lo.x <= part.hi.x)) continue;  // no part in this slab (cannot happen for a non-degenerate slab)
    const Vec3 margin{pad, pad, pad};
    out.push_back({part.lo - margin, part.hi + margin});
  }
  return static_cast<int>(out.size() - first);
}

}  // namespace rayfarm
