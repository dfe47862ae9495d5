// Ear clipping for planar polygons, after Eberly, "Triangulation by Ear
// Clipping" (Geometric Tools, 2002): project onto the coordinate plane where the
// polygon's normal is largest, orient the projection counter-clockwise, and
// repeatedly cut off a convex vertex whose triangle contains no other vertex,
// the one whose triangle fills its box best first. O(n^2) per polygon: each
// cut looks at its two neighbours again and the ring once for the best ear.
#include "tracer/triangulate.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "tracer/triangle_pieces.h"

namespace rayfarm {
namespace {

// Areas below this fraction of the squared bounding-box diagonal count as zero.
// NFF coordinates carry ~6 significant digits (%g), so round-off in a collinear
// triple is ~1e-16 relative; 1e-12 separates that from any real sliver.
constexpr double kAreaEpsilon = 1e-12;

struct Point2 {
  double x, y;
};

// Twice the signed area of triangle abc, positive when counter-clockwise.
double orient2(const Point2& a, const Point2& b, const Point2& c) {
  return (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
}

double extent_squared(const Vec3* v, uint32_t n) {
  Vec3 lo = v[0], hi = v[0];
  for (uint32_t i = 1; i < n; ++i) {
    lo = {std::min(lo.x, v[i].x), std::min(lo.y, v[i].y), std::min(lo.z, v[i].z)};
    hi = {std::max(hi.x, v[i].x), std::max(hi.y, v[i].y), std::max(hi.z, v[i].z)};
  }
  return dot(hi - lo, hi - lo);
}

// Drops the normal's dominant axis (least area distortion) and orders the two
// remaining axes so that the polygon is counter-clockwise in the projection.
std::vector<Point2> project_ccw(const Vec3* v, uint32_t n, const Vec3& normal) {
  const double ax = std::abs(normal.x), ay = std::abs(normal.y), az = std::abs(normal.z);
  const int axis = (ax >= ay && ax >= az) ? 0 : (ay >= az ? 1 : 2);
  // Cyclic successors keep the right-handed orientation: (y,z), (z,x), (x,y).
  int u = (axis + 1) % 3, w = (axis + 2) % 3;
  if (normal[axis] < 0) std::swap(u, w);
  std::vector<Point2> p(n);
  for (uint32_t i = 0; i < n; ++i) p[i] = {v[i][u], v[i][w]};
  return p;
}

// Inclusive test: a point on an edge of the candidate ear blocks it, because the
// diagonal would then touch another vertex.
bool in_triangle(const Point2& a, const Point2& b, const Point2& c, const Point2& q) {
  return orient2(a, b, q) >= 0 && orient2(b, c, q) >= 0 && orient2(c, a, q) >= 0;
}

bool same(const Point2& a, const Point2& b) { return a.x == b.x && a.y == b.y; }

// Counter-clockwise polygon as a doubly linked ring of vertex indices, cut
// ear by ear, always the ear whose triangle fills its box best
// (box_emptiness()), the lowest vertex index on a tie. Walking the
// ring and cutting the next ear met instead fans a gear's 144-gon out from a
// few vertices into long slivers at every angle, whose boxes are mostly empty
// (gears: 660 pieces a face, triangle_pieces.h); the best ear first cuts the
// teeth and then ever coarser rings of the same circle, whose triangles lie
// flatter in their boxes (none a sliver: 94 pieces a face, most of them two
// neighbouring triangles).
class EarClipper {
 public:
  EarClipper(const Vec3* vertices, std::vector<Point2> points, double tiny)
      : v_(vertices), p_(std::move(points)), prev_(p_.size()), next_(p_.size()), cost_(p_.size()), tiny_(tiny) {
    const uint32_t n = static_cast<uint32_t>(p_.size());
    for (uint32_t i = 0; i < n; ++i) {
      prev_[i] = (i + n - 1) % n;
      next_[i] = (i + 1) % n;
    }
    remaining_ = n;
    for (uint32_t i = 0; i < n; ++i) cost_[i] = ear_cost(i);
  }

  void run(std::vector<uint32_t>& out) {
    while (remaining_ > 3) {
      uint32_t best = pick();
      if (best == kNone) {
        // No ear in the cached costs: a cut can make a vertex an ear that was
        // not (one it blocked is gone), so look at every vertex again first.
        for (uint32_t i = first_; ; i = next_[i]) {
          cost_[i] = ear_cost(i);
          if (next_[i] == first_) break;
        }
        best = pick();
      }
      if (best == kNone) {
        // Not one ear: the input is not simple (self-touching or rounding).
        // Cut the most convex corner anyway so the loop always ends.
        best = most_convex(first_);
        if (orient2(p_[prev_[best]], p_[best], p_[next_[best]]) <= tiny_) return;
      }
      if (cost_[best] != kCollinear) emit(prev_[best], best, next_[best], out);
      cut(best);
    }
    const uint32_t cur = first_;
    if (orient2(p_[prev_[cur]], p_[cur], p_[next_[cur]]) > tiny_) emit(prev_[cur], cur, next_[cur], out);
  }

 private:
  static constexpr uint32_t kNone = ~0u;
  // Collinear, repeated or spike vertices go first: dropping one removes no
  // area. Not an ear: never picked.
  static constexpr double kCollinear = -1, kNotEar = HUGE_VAL;

  double ear_cost(uint32_t b) const {
    const uint32_t a = prev_[b], c = next_[b];
    const double area = orient2(p_[a], p_[b], p_[c]);
    if (std::abs(area) <= tiny_) return kCollinear;
    if (!(area > 0) || !is_ear(a, b, c)) return kNotEar;
    // Rays are tested against a triangle when they enter its box
    // (triangle_pieces.h), so a triangulation of tight boxes is a fast one.
    return std::min(box_emptiness(v_[a], v_[b], v_[c]), std::numeric_limits<double>::max());
  }

  // The vertex with the lowest cost, the lowest index on a tie; kNone when
  // no vertex is an ear.
  uint32_t pick() const {
    uint32_t best = kNone;
    for (uint32_t i = first_; ; i = next_[i]) {
      if (cost_[i] != kNotEar && (best == kNone || cost_[i] < cost_[best] || (cost_[i] == cost_[best] && i < best)))
        best = i;
      if (next_[i] == first_) break;
    }
    return best;
  }

  bool is_ear(uint32_t a, uint32_t b, uint32_t c) const {
    for (uint32_t j = next_[c]; j != a; j = next_[j]) {
      const Point2& q = p_[j];
      // A vertex repeated elsewhere in the ring (polygon touching itself) is
      // the ear's own corner, not an obstacle.
      if (same(q, p_[a]) || same(q, p_[b]) || same(q, p_[c])) continue;
      if (in_triangle(p_[a], p_[b], p_[c], q)) return false;
    }
    return true;
  }

  uint32_t most_convex(uint32_t start) const {
    uint32_t best = start;
    double best_area = -INFINITY;
    uint32_t i = start;
    do {
      const double area = orient2(p_[prev_[i]], p_[i], p_[next_[i]]);
      if (area > best_area) best_area = area, best = i;
      i = next_[i];
    } while (i != start);
    return best;
  }

  // Takes vertex i out of the ring; only its two neighbours' corners change.
  void cut(uint32_t i) {
    const uint32_t a = prev_[i], c = next_[i];
    next_[a] = c;
    prev_[c] = a;
    --remaining_;
    if (first_ == i) first_ = c;
    cost_[a] = ear_cost(a);
    cost_[c] = ear_cost(c);
  }

  static void emit(uint32_t a, uint32_t b, uint32_t c, std::vector<uint32_t>& out) {
    out.insert(out.end(), {a, b, c});
  }

  const Vec3* v_;
  std::vector<Point2> p_;
  std::vector<uint32_t> prev_, next_;
  std::vector<double> cost_;  // per vertex: its ear's box_emptiness(), or kCollinear / kNotEar
  uint32_t remaining_ = 0;
  uint32_t first_ = 0;  // a vertex still in the ring
  double tiny_;
};

bool is_convex_quad(const std::vector<Point2>& p, double tiny) {
  for (uint32_t i = 0; i < 4; ++i)
    if (orient2(p[(i + 3) % 4], p[i], p[(i + 1) % 4]) <= tiny) return false;
  return true;
}

}  // namespace

Vec3 polygon_normal(const Vec3* v, uint32_t n) {
  Vec3 normal;
  for (uint32_t i = 0; i < n; ++i) {
    const Vec3& a = v[i];
    const Vec3& b = v[(i + 1) % n];
    normal += {(a.y - b.y) * (a.z + b.z), (a.z - b.z) * (a.x + b.x), (a.x - b.x) * (a.y + b.y)};
  }
  return normal;
}

bool polygon_is_degenerate(const Vec3* v, uint32_t n) {
  if (n < 3) return true;
  // Written so that NaN compares as degenerate.
  return !(length(polygon_normal(v, n)) > kAreaEpsilon * extent_squared(v, n));
}

std::vector<uint32_t> triangulate_polygon(const Vec3* vertices, uint32_t n) {
  std::vector<uint32_t> out;
  if (polygon_is_degenerate(vertices, n)) return out;
  if (n == 3) return {0, 1, 2};
  const Vec3 normal = polygon_normal(vertices, n);
  const double tiny = kAreaEpsilon * extent_squared(vertices, n);
  std::vector<Point2> p = project_ccw(vertices, n, normal);
  if (n == 4 && is_convex_quad(p, tiny)) return {0, 1, 2, 0, 2, 3};
  out.reserve(3 * (n - 2));
  EarClipper(vertices, std::move(p), tiny).run(out);
  return out;
}

}  // namespace rayfarm
