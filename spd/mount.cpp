// mount: a fractal mountain (Carpenter-style midpoint displacement on a square
// grid of 2^size cells per side, two triangles per cell) with a pyramid of four
// glass spheres in front of it: refraction dominates the render. 1 light.
// The random numbers come from the original, deliberately kept "faulty" hash
// and a tiny restartable LCG, so the terrain matches the SPD exactly.

#include <cmath>

#include "spd/generators.h"

namespace rayfarm::spd {
namespace {

constexpr double kFractalDimension = 2.2;  // between 2 and 3: sets the roughness
constexpr long kMountainNo = 21;           // seed offset; another value, another mountain
constexpr double kCorner = -1.0;           // lower-left corner of the square, x and y
constexpr double kWidth = 2.0;

// Haines' original hash of a grid index (he asks that it be kept for
// comparability, although it repeats). Valid for size <= 7: the shifts
// are 23-size, 15-size and 7-size bits.
unsigned long old_hash(int a, int b, int size) {
  const auto ua = static_cast<unsigned long>(a);
  const auto ub = static_cast<unsigned long>(b);
  return ((ua << (23 - size)) + (ub << (15 - size)) + (ua << (7 - size))) & 0xffffUL;
}

// Gaussian deviate from a seed: polar Box-Muller over an LCG (Numerical
// Recipes' portable generator, M = 134456, a = 8121, c = 28411) that restarts
// from the seed on every call, so a grid point always gets the same value.
double gauss_rand(long seed) {
  constexpr long kM = 134456, kA = 8121, kC = 28411;
  long u1 = 0, u2 = seed;
  double v1 = 0.0, v2 = 0.0, r = 0.0;
  do {
    u1 = (kC + u2 * kA) % kM;
    u2 = (kC + u1 * kA) % kM;
    // The original expands "u * 2.0 * 1.0/M": multiply first, then divide.
    v1 = u1 * 2.0 * 1.0 / kM - 1.0;
    v2 = u2 * 2.0 * 1.0 / kM - 1.0;
    r = v1 * v1 + v2 * v2;
  } while (r >= 1.0);
  return v1 * std::sqrt(-2.0 * std::log(r) / r);
}

// Four mutually touching spheres of radius center.w around `center`: one on
// top, three below rotated by 120 degrees.
void write_sphere_pyramid(const Coord& center, NffWriter& out) {
  Coord axis = {1.0, 1.0, 0.0, 0.0};
  normalize(axis);
  const double angle = std::acos(-1.0 / 3.0);  // tetrahedral angle
  const Coord top = {0.0, 0.0, center.w * std::sqrt(3.0 / 2.0), 0.0};
  out.sphere(add3(center, top));
  Coord tilted = transform_vector(top, axis_rotate_matrix(axis, angle));
  for (int i = 0; i < 3; ++i) {
    Coord s = transform_vector(tilted, rotate_matrix(Axis::Z, double(i) * 2.0 * kPi / 3.0));
    s = add3(s, center);
    s.w = center.w;
    out.sphere(s);
  }
}

struct Terrain {
  int size;          // the size factor: 2^size cells per side
  double cells;      // 2^size as a double
  double roughness;  // rise per unit half-side
};

// Corner heights of a square: lower-left, lower-right, upper-right, upper-left.
struct Heights {
  double ll, lr, ur, ul;
};

double midpoint_noise(const Terrain& t, int x, int y) {
  return gauss_rand(kMountainNo + static_cast<long>(old_hash(x, y, t.size)));
}

void write_cell(const Terrain& t, int x, int y, const Heights& h, NffWriter& out) {
  const double l = kCorner + double(x) * kWidth / t.cells;
  const double r = kCorner + double(x + 1) * kWidth / t.cells;
  const double b = kCorner + double(y) * kWidth / t.cells;
  const double u = kCorner + double(y + 1) * kWidth / t.cells;
  const Coord ll = {l, b, h.ll, 0.0}, lr = {r, b, h.lr, 0.0};
  const Coord ur = {r, u, h.ur, 0.0}, ul = {l, u, h.ul, 0.0};
  const Coord first[3] = {ll, lr, ur};
  const Coord second[3] = {ur, ul, ll};
  out.polygon(first, 3);
  out.polygon(second, 3);
}

// Square with lower-left grid index (x, y) and `width` cells: displace the four
// edge midpoints and the centre, recurse into LL, LR, UR, UL quadrants.
void grow(const Terrain& t, int width, int x, int y, const Heights& h, NffWriter& out) {
  if (width == 1) {
    write_cell(t, x, y, h, out);
    return;
  }
  const int half = width >> 1;
  const double half_side = double(half) * kWidth / t.cells;
  const double rise = half_side * t.roughness;
  const double lower = (h.ll + h.lr) / 2.0 + rise * midpoint_noise(t, x + half, y);
  const double right = (h.lr + h.ur) / 2.0 + rise * midpoint_noise(t, x + width, y + half);
  const double upper = (h.ur + h.ul) / 2.0 + rise * midpoint_noise(t, x + half, y + width);
  const double left = (h.ul + h.ll) / 2.0 + rise * midpoint_noise(t, x, y + half);
  // The centre is sqrt(2) times further from its neighbours than an edge midpoint.
  const double middle =
      (h.ll + h.lr + h.ur + h.ul) / 4.0 + 1.4142136 * rise * midpoint_noise(t, x + half, y + half);
  grow(t, half, x, y, {h.ll, lower, middle, left}, out);
  grow(t, half, x + half, y, {lower, h.lr, right, middle}, out);
  grow(t, half, x + half, y + half, {middle, right, h.ur, upper}, out);
  grow(t, half, x, y + half, {left, middle, upper, h.ul}, out);
}

}  // namespace

void write_mount(int size, NffWriter& out) {
  write_sky_and_view(out, {-1.6, 1.6, 1.7}, {0.0, 0.0, 0.0}, {0.0, 0.0, 1.0}, 0.01);
  out.light({-100.0, -100.0, 100.0});

  out.surface({1.0, 1.0, 1.0, /*kd*/ 0.1, /*ks*/ 0.1, /*phong*/ 6.7, /*kt*/ 0.9, /*ior*/ 1.5});
  write_sphere_pyramid({-0.8, 0.8, 1.0, 0.17}, out);

  out.surface({0.5, 0.45, 0.35, /*kd*/ 1.0, /*ks*/ 0.0, /*phong*/ 0.0, /*kt*/ 0.0, /*ior*/ 0.0});
  const int cells = 1 << size;
  // Each halving of the scale scales the variance by ratio^2 (Carpenter).
  const double ratio = 2.0 / std::exp(std::log(2.0) / (kFractalDimension - 1.0));
  const Terrain terrain = {size, double(cells), std::sqrt(ratio * ratio - 1.0)};
  grow(terrain, cells, 0, 0, {0.0, 0.0, 0.0, 0.0}, out);
}

}  // namespace rayfarm::spd
