// rings: a pyramid of "dodecahedral ring" objects seen from its apex. Each
// object is 6 pentagonal rings through the edge midpoints of a dodecahedron,
// built from 30 cylinders and 30 joint spheres, all reflective (Ks 0.2);
// a white wall behind catches the shadows of 3 lights. High depth complexity.

#include <cmath>

#include "spd/generators.h"

namespace rayfarm::spd {
namespace {

constexpr double kTubeRadius = 0.07412;  // of every cylinder and joint sphere

// The 30 ring points of one object, scaled to fit a unit sphere: ring 0 is a
// pentagon in z = 0, rings 1..5 are it tilted about X by the dodecahedron's
// dihedral-derived angle and turned about Z by odd tenths of a turn.
struct RingPoints {
  Coord p[30];
};

RingPoints make_ring_points(double tube_radius) {
  RingPoints rp;
  const double scale = 1.0 / (1.0 + tube_radius);
  for (int k = 0; k < 5; ++k) {
    rp.p[k] = {scale * std::cos(double(k) * 2.0 * kPi / 5.0),
               scale * std::sin(double(k) * 2.0 * kPi / 5.0), 0.0, 0.0};
  }
  const double x_rotation = 2.0 * std::acos(std::cos(kPi / 3.0) / std::sin(kPi / 5.0));
  const Matrix x_matrix = rotate_matrix(Axis::X, x_rotation);
  for (int ring = 1; ring < 6; ++ring) {
    const double z_rotation = kPi * (2.0 * double(ring - 1) + 1.0) / 5.0;
    const Matrix z_matrix = rotate_matrix(Axis::Z, z_rotation);
    for (int k = 0; k < 5; ++k)
      rp.p[5 * ring + k] = transform_point(transform_point(rp.p[k], x_matrix), z_matrix);
  }
  return rp;
}

// Ring colours cycle red, green, blue and their complements.
constexpr double kRingColor[6][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1},
                                     {0, 1, 1}, {1, 0, 1}, {1, 1, 0}};

void write_ring_object(const RingPoints& rp, const Coord& offset, NffWriter& out) {
  for (int e = 0; e < 30; ++e) {
    int prev = e - 1;
    if (e % 5 == 0) {
      prev = e + 4;
      const double* c = kRingColor[e / 5];
      out.surface({c[0], c[1], c[2], /*kd*/ 0.5, /*ks*/ 0.2, /*phong*/ 37.0, /*kt*/ 0.0,
                   /*ior*/ 0.0});
    }
    Coord base = add3(rp.p[e], offset);
    Coord apex = add3(rp.p[prev], offset);
    base.w = apex.w = kTubeRadius;
    out.cone(base, apex);
    out.sphere(base);
  }
}

}  // namespace

void write_rings(int size, NffWriter& out) {
  // Layers are spread along y so that each one exactly fills the 45-degree view.
  const double spread = 1 / std::sin(kPi / 8.0);
  const double y_diff = spread;
  const double xz_diff = 1.0;

  const Coord from = {-1.0, -spread, 0.5, 0.0};
  write_sky_and_view(out, from, {from.x, from.y + 1.0, from.z}, {0.0, 0.0, 1.0}, 1.0);
  out.light({3.0, -spread, 3.0});
  out.light({-4.0, -spread, 1.0});
  out.light({2.0, -spread, -4.0});

  // The wall just spans the 45-degree view plus 1%.
  out.surface({1.0, 1.0, 1.0, /*kd*/ 1.0, /*ks*/ 0.0, /*phong*/ 0.0, /*kt*/ 0.0, /*ior*/ 0.0});
  const double wall_y = y_diff * (size + 1);
  const double half = 1.01 * (wall_y - from.y) * std::tan(kPi / 8.0);
  const Coord wall[4] = {{half + from.x, wall_y, half + from.z, 0.0},
                         {-half + from.x, wall_y, half + from.z, 0.0},
                         {-half + from.x, wall_y, -half + from.z, 0.0},
                         {half + from.x, wall_y, -half + from.z, 0.0}};
  out.polygon(wall, 4);

  const RingPoints rp = make_ring_points(kTubeRadius);
  for (int depth = 0; depth < size; ++depth) {
    Coord offset;
    offset.y = y_diff * double(depth + 1);
    for (int iz = 0; iz <= depth; ++iz) {
      offset.z = xz_diff * double(2 * iz - depth);
      for (int ix = 0; ix <= depth; ++ix) {
        offset.x = xz_diff * double(2 * ix - depth);
        write_ring_object(rp, offset, out);
      }
    }
  }
}

}  // namespace rayfarm::spd
