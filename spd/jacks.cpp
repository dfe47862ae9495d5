// jacks (Alexander Enzmann): a recursive "jack" (three crossed rods with balls
// on the six ends) with half-size copies in the 8 octants, `size` levels deep:
// 9 * (8^size - 1) / 7 primitives. 1 light, dark purple background.
// The original places the pieces through a transform stack and writes them
// transformed; NFF spheres and cylinders stay round under the uniform scale.

#include <cmath>

#include "spd/generators.h"

namespace rayfarm::spd {
namespace {

// Uniform scale factor of a transform: the length of its first row (what the
// SPD's matrix "unwind", after Graphics Gems II, reports as the x scale).
double uniform_scale(const Matrix& tx) {
  Coord row = {tx.m[0][0], tx.m[0][1], tx.m[0][2], 0.0};
  return std::fabs(normalize(row));
}

void write_transformed_sphere(const Coord& c, const Matrix& tx, NffWriter& out) {
  Coord s = transform_point(c, tx);
  s.w = c.w * uniform_scale(tx);
  out.sphere(s);
}

void write_transformed_rod(const Coord& base, const Coord& apex, const Matrix& tx, NffWriter& out) {
  const double scale = uniform_scale(tx);
  Coord b = transform_point(base, tx);
  Coord a = transform_point(apex, tx);
  b.w = base.w * scale;
  a.w = apex.w * scale;
  out.cone(b, a);
}

// One jack in the unit cube, shrunk to 3/4 so neighbouring copies do not touch.
// Transforms compose as in the SPD: a new operation multiplies from the left.
void write_jack(const Matrix& parent, NffWriter& out) {
  const Matrix tx = multiply(scale_matrix({0.75, 0.75, 0.75, 0.0}), parent);
  write_transformed_rod({-1, 0, 0, 0.1}, {1, 0, 0, 0.1}, tx, out);
  write_transformed_rod({0, -1, 0, 0.1}, {0, 1, 0, 0.1}, tx, out);
  write_transformed_rod({0, 0, -1, 0.1}, {0, 0, 1, 0.1}, tx, out);
  const Coord ends[6] = {{1, 0, 0, 0.2},  {0, 1, 0, 0.2},  {0, 0, 1, 0.2},
                         {-1, 0, 0, 0.2}, {0, -1, 0, 0.2}, {0, 0, -1, 0.2}};
  for (const Coord& e : ends) write_transformed_sphere(e, tx, out);
}

void write_recursive_jack(int depth, int max_depth, const Matrix& tx, NffWriter& out) {
  write_jack(tx, out);
  if (depth >= max_depth) return;
  for (double i = -0.5; i <= 0.5; i += 1)
    for (double j = -0.5; j <= 0.5; j += 1)
      for (double k = -0.5; k <= 0.5; k += 1) {
        const Matrix moved = multiply(translate_matrix({i, j, k, 0.0}), tx);
        const Matrix child = multiply(scale_matrix({0.5, 0.5, 0.5, 0.0}), moved);
        write_recursive_jack(depth + 1, max_depth, child, out);
      }
}

}  // namespace

void write_jacks(int size, NffWriter& out) {
  out.background(0.2, 0.05, 0.2);
  View view;
  view.from = {0.0, 0.0, -8.0};
  view.at = {0.0, 0.0, 0.0};
  view.up = {0.0, 1.0, 0.0};
  view.angle = 25.0;
  view.hither = 0.001;
  view.resx = view.resy = 256;
  out.viewpoint(view);
  out.light({-10.0, 3.0, -20.0});

  Matrix root = multiply(rotate_matrix(Axis::X, -30 * kPi / 180.0), identity_matrix());
  root = multiply(rotate_matrix(Axis::Y, -20 * kPi / 180.0), root);
  out.surface({0.737, 0.561, 0.561, /*kd*/ 0.7, /*ks*/ 0.7, /*phong*/ 20.0, /*kt*/ 0.0,
               /*ior*/ 1.0});
  write_recursive_jack(1, size, root, out);
}

}  // namespace rayfarm::spd
