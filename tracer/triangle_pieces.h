// Tighter boxes for long thin triangles. A sliver lying diagonally has a box
// many times its own area, and every ray through that box costs an exact test
// (gears, when ear clipping still fanned its faces into slivers: 7-8 triangle
// tests per ray; triangulate.cpp now avoids them where it can). Embree
// splits such triangles itself ("spatial splits"), but not user geometry, so rayfarm does it: a triangle is handed to Embree as
// pieces, each the box of the triangle's part within a slab along the box's
// longest axis, like the slices of a cone. A piece only decides when the exact
// test runs, never its result: every piece tests the whole triangle.
#pragma once

#include <vector>

#include "tracer/box.h"
#include "tracer/vec3.h"

namespace rayfarm {

// How much of its bounding box triangle (a, b, c) leaves empty: box surface
// over triangle area, 4 for a right triangle filling half of a flat
// axis-aligned box (the least there is), 2 L / w for a sliver of length L and
// width w lying across its box; HUGE_VAL for a triangle without area.
double box_emptiness(const Vec3& a, const Vec3& b, const Vec3& c);

// How many pieces triangle (a, b, c) is worth: 1 for a triangle that fills its
// box reasonably (most meshes: box surface below kWholeTriangleRatio times its
// area), up to kMaxTrianglePieces for a diagonal sliver.
inline constexpr double kWholeTriangleRatio = 12;
inline constexpr int kMaxTrianglePieces = 16;
int triangle_piece_count(const Vec3& a, const Vec3& b, const Vec3& c);

// Whether two triangles, whose boxes are `a` and `b` and together `both`,
// are worth one piece that tests both: a ray through `both` then costs one
// callback and one walk to a leaf instead of a ray through each box costing
// its own. Yes when the joint box's surface (what the chance of a ray
// entering it goes by) is at most kPairedSurfaceRatio of the two boxes'
// together: a quad's halves (about a half), or a mesh's two facets across
// the diagonal of a bent quad; not two side by side (about 1).
inline constexpr double kPairedSurfaceRatio = 0.75;
bool worth_pairing(const Box& both, const Box& a, const Box& b);

// `count` boxes that together hold every point of the triangle: the boxes of
// its parts in `count` equal slabs along the longest axis of its box.
std::vector<Box> triangle_pieces(const Vec3& a, const Vec3& b, const Vec3& c, int count);
// The same boxes appended to `out` (no vector per triangle); returns how many.
int append_triangle_pieces(const Vec3& a, const Vec3& b, const Vec3& c, int count, std::vector<Box>& out);

}  // namespace rayfarm
