// Polygon triangulation for NFF `p`/`pp` entities. The SPD gears scene has
// concave 144-vertex faces, where a triangle fan would fill the gaps between the
// teeth, so polygons are split by ear clipping (Eberly, "Triangulation by Ear
// Clipping", 2002) in the plane the polygon projects onto with the least
// distortion, the ear whose triangle fills its bounding box best first, so
// that few triangles are slivers (a ray entering a triangle's box costs a test).
#pragma once

#include <cstdint>
#include <vector>

#include "tracer/vec3.h"

namespace rayfarm {

// Newell's normal of a polygon (Sutherland, Sproull & Schumacker 1974): robust
// for concave and slightly non-planar polygons, points along the right-handed
// counter-clockwise normal, and has length 2 * area for a planar polygon.
Vec3 polygon_normal(const Vec3* vertices, uint32_t n);

// True when a planar polygon has no area worth drawing: its Newell normal is
// below a tolerance relative to the squared extent of its bounding box.
bool polygon_is_degenerate(const Vec3* vertices, uint32_t n);

// Splits a planar simple polygon (convex or concave, any winding) into triangles
// by ear clipping in the polygon's dominant projection plane. Returns 3*k indices
// into `vertices` (0..n-1), each triangle wound like the polygon. Degenerate
// input (repeated or collinear vertices, zero area) yields only the non-degenerate
// triangles, possibly none. Never loops forever.
std::vector<uint32_t> triangulate_polygon(const Vec3* vertices, uint32_t n);

}  // namespace rayfarm
