// Axis-aligned boxes: what Embree walks, and what the screen footprint
// projects.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <initializer_list>

#include "tracer/vec3.h"

namespace rayfarm {

struct Box {
  Vec3 lo, hi;
};

// Grows the box to hold p.
inline void grow(Box& box, const Vec3& p) {
  box.lo = {std::min(box.lo.x, p.x), std::min(box.lo.y, p.y), std::min(box.lo.z, p.z)};
  box.hi = {std::max(box.hi.x, p.x), std::max(box.hi.y, p.y), std::max(box.hi.z, p.z)};
}

// The smallest box holding every point.
inline Box box_of(std::initializer_list<Vec3> points) {
  Box box{{HUGE_VAL, HUGE_VAL, HUGE_VAL}, {-HUGE_VAL, -HUGE_VAL, -HUGE_VAL}};
  for (const Vec3& p : points) grow(box, p);
  return box;
}

// The box's eight corners; bit 0 of the index picks hi.x, bit 1 hi.y, bit 2 hi.z.
inline std::array<Vec3, 8> box_corners(const Box& box) {
  std::array<Vec3, 8> corners;
  for (int c = 0; c < 8; ++c) {
    corners[c] = {c & 1 ? box.hi.x : box.lo.x, c & 2 ? box.hi.y : box.lo.y, c & 4 ? box.hi.z : box.lo.z};
  }
  return corners;
}

}  // namespace rayfarm
