// balls: the "sphereflake". A sphere of radius r carries 9 tangent children of
// radius r/3, recursively `size` levels deep, over a square floor; all spheres
// are mirrors (Ks 0.5), lit by 3 lights. sum_{k=0..size} 9^k spheres + 1 floor.
// Output is depth-first, so memory is O(size) however large the scene.

#include <cmath>

#include "spd/generators.h"

namespace rayfarm::spd {
namespace {

// The 9 child directions in the parent's frame (+Z = away from the grandparent):
// a trio tilted by asin(2/sqrt 6) about (1,-1,0)/sqrt 2, repeated at 0, 120 and
// 240 degrees about Z: 6 round the "equator" and 3 leaning "up".
struct ChildSet {
  Coord dir[9];
};

ChildSet make_child_set() {
  const double d = 1.0 / std::sqrt(2.0);
  Coord trio[3] = {{d, d, 0.0, 0.0}, {d, 0.0, -d, 0.0}, {0.0, d, -d, 0.0}};
  Coord axis = {1.0, -1.0, 0.0, 0.0};
  normalize(axis);
  const Matrix tilt = axis_rotate_matrix(axis, std::asin(2.0 / std::sqrt(6.0)));
  for (Coord& t : trio) t = transform_coord(t, tilt);
  ChildSet set;
  for (int s = 0; s < 3; ++s) {
    const Matrix spin = rotate_matrix(Axis::Z, s * 2.0 * kPi / 3.0);
    for (int v = 0; v < 3; ++v) set.dir[s * 3 + v] = transform_coord(trio[v], spin);
  }
  return set;
}

// Rotation taking +Z onto `dir` (nearly unit: children's directions are
// recomputed from positions). Near +-Z the axis is ill-defined, hence the cases.
Matrix frame_towards(const Coord& dir) {
  if (dir.z >= 0.9999) return identity_matrix();
  if (dir.z <= -0.9999) return rotate_matrix(Axis::Y, kPi);
  const Coord z_axis = {0.0, 0.0, 1.0, 0.0};
  Coord axis = cross(z_axis, dir);
  normalize(axis);
  return axis_rotate_matrix(axis, std::acos(dot(z_axis, dir)));
}

// `center.w` is the radius; `direction.w` the child/parent radius ratio (1/3).
void write_flake(int depth, const Coord& center, const Coord& direction, const ChildSet& set,
                 NffWriter& out) {
  out.sphere(center);
  if (depth <= 0) return;
  const Matrix mx = frame_towards(direction);
  const double scale = center.w * (1.0 + direction.w);  // parent-to-child distance
  for (const Coord& d : set.dir) {
    Coord child = transform_coord(d, mx);
    child.x = child.x * scale + center.x;
    child.y = child.y * scale + center.y;
    child.z = child.z * scale + center.z;
    child.w = center.w * direction.w;
    Coord child_dir = sub3(child, center);
    child_dir.x /= scale;
    child_dir.y /= scale;
    child_dir.z /= scale;
    child_dir.w = direction.w;
    write_flake(depth - 1, child, child_dir, set, out);
  }
}

}  // namespace

void write_balls(int size, NffWriter& out) {
  write_sky_and_view(out, {2.1, 1.3, 1.7}, {0.0, 0.0, 0.0}, {0.0, 0.0, 1.0}, 0.01);
  out.light({4.0, 3.0, 2.0});
  out.light({1.0, -4.0, 4.0});
  out.light({-3.0, 1.0, 5.0});

  const double radius = 1.0;  // of the sphere enclosing the whole flake
  out.surface({1.0, 0.75, 0.33, /*kd*/ 0.8, /*ks*/ 0.0, /*phong*/ 0.0, /*kt*/ 0.0, /*ior*/ 1.0});
  const double fx = 12.0 * radius, fy = 12.0 * radius, fz = -radius / 2.0;
  const Coord floor[4] = {
      {fx, fy, fz, 0.0}, {-fx, fy, fz, 0.0}, {-fx, -fy, fz, 0.0}, {fx, -fy, fz, 0.0}};
  out.polygon(floor, 4);

  out.surface({1.0, 0.9, 0.7, /*kd*/ 0.5, /*ks*/ 0.5, /*phong*/ 37.0, /*kt*/ 0.0, /*ior*/ 1.0});
  const ChildSet set = make_child_set();
  write_flake(size, {0.0, 0.0, 0.0, radius / 2.0}, {0.0, 0.0, 1.0, 1.0 / 3.0}, set, out);
}

}  // namespace rayfarm::spd
