// tree: Aono & Kunii's botanical tree (IEEE CG&A, May 1984): every branch is a
// cone capped by a sphere and forks into two smaller branches, `size` levels
// deep, over a green field; 7 lights. 2^(size+1) - 1 cones and spheres + 1 polygon.

#include "spd/generators.h"

namespace rayfarm::spd {
namespace {

// Shape of the tree (Aono & Kunii's parameters): branching angles and length
// contractions of the two children, radius taper, and divergence about the axis.
constexpr double kBranchAngle[2] = {40.0, 25.0};
constexpr double kContraction[2] = {0.65, 0.70};
constexpr double kDiameterRatio = 0.67;
constexpr double kDivergence = 140.0;
constexpr double kWidthHeightRatio = 0.15;

// Child frame relative to its parent: tilt about X, turn about Z, shrink, and
// move to the parent's tip (translation row z = 1).
Matrix branch_matrix(int child) {
  const double divergence = child == 0 ? 90.0 : kDivergence + 90.0;
  const Matrix tilt = rotate_matrix(Axis::X, kBranchAngle[child] * kPi / 180.0);
  const Matrix turn = rotate_matrix(Axis::Z, divergence * kPi / 180.0);
  Matrix shrink = identity_matrix();
  shrink.m[0][0] = shrink.m[1][1] = shrink.m[2][2] = kContraction[child];
  shrink.m[3][2] = 1.0;
  return multiply(multiply(tilt, turn), shrink);
}

void grow(const Matrix& frame, double scale, int depth, const Matrix (&branch)[2], NffWriter& out) {
  Coord base = transform_point({0.0, 0.0, 0.0, 0.0}, frame);
  base.w = scale * kWidthHeightRatio;
  Coord apex = transform_point({0.0, 0.0, 1.0, 0.0}, frame);
  apex.w = base.w * kDiameterRatio;
  out.cone(base, apex);
  out.sphere(apex);
  if (depth <= 0) return;
  for (const Matrix& b : branch)
    grow(multiply(b, frame), scale * kDiameterRatio, depth - 1, branch, out);
}

}  // namespace

void write_tree(int size, NffWriter& out) {
  write_sky_and_view(out, {4.5, 0.4, 2.0}, {0.0, 0.0, 1.5}, {0.0, 0.0, 1.0}, 1.0);
  const Coord lights[7] = {{-5.0, 5.0, 50.0},   {30.0, -30.0, 30.0}, {-40.0, -30.0, 20.0},
                           {10.0, 30.0, 40.0},  {-30.0, 40.0, 10.0}, {50.0, 25.0, 20.0},
                           {-10.0, -60.0, 30.0}};
  for (const Coord& l : lights) out.light(l);

  out.surface({0.2, 0.7, 0.2, /*kd*/ 1.0, /*ks*/ 0.0, /*phong*/ 0.0, /*kt*/ 0.0, /*ior*/ 0.0});
  const Coord field[4] = {{50.0, 50.0, 0.0, 0.0},
                          {-50.0, 50.0, 0.0, 0.0},
                          {-50.0, -50.0, 0.0, 0.0},
                          {50.0, -50.0, 0.0, 0.0}};
  out.polygon(field, 4);

  out.surface({0.55, 0.4, 0.2, /*kd*/ 1.0, /*ks*/ 0.0, /*phong*/ 0.0, /*kt*/ 0.0, /*ior*/ 0.0});
  const Matrix branch[2] = {branch_matrix(0), branch_matrix(1)};
  grow(identity_matrix(), 1.0, size, branch, out);
}

}  // namespace rayfarm::spd
