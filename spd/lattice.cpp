// lattice (Antonio Costa): a cubic lattice of (size+1)^3 shiny spheres joined
// to their neighbours by 3 size (size+1)^2 matte cylinders, seen from inside
// with a 60-degree view; 6 lights.

#include <cmath>

#include "spd/generators.h"

namespace rayfarm::spd {
namespace {

constexpr double kSphereRadius = 1.0 / 4.0;  // per unit cell
constexpr double kCylinderRadius = 1.0 / 16.0;

constexpr Surface kSphere = {0.9,        0.9, 0.9, /*kd*/ 0.5, /*ks*/ 0.5, /*phong*/ 37.0,
                             /*kt*/ 0.0,
                             /*ior*/ 0.0};
constexpr Surface kRod[3] = {
    {0.9, 0.1, 0.1, /*kd*/ 0.99, /*ks*/ 0.0, /*phong*/ 0.0, /*kt*/ 0.0, /*ior*/ 0.0},
    {0.1, 0.9, 0.1, /*kd*/ 0.99, /*ks*/ 0.0, /*phong*/ 0.0, /*kt*/ 0.0, /*ior*/ 0.0},
    {0.1, 0.1, 0.9, /*kd*/ 0.99, /*ks*/ 0.0, /*phong*/ 0.0, /*kt*/ 0.0, /*ior*/ 0.0}};

}  // namespace

void write_lattice(int size, NffWriter& out) {
  const double inv = 1.0 / double(size);
  const double sphere_r = kSphereRadius / double(size);
  const double rod_r = kCylinderRadius / double(size);
  // Rods start just inside the sphere surface (where the thinner cylinder
  // meets it), pulled in by 1% so no crack shows.
  const double delta = (sphere_r * (1.0 - std::sqrt(kCylinderRadius / kSphereRadius))) * 0.99;

  const double view_x = (double(size >> 1) + 0.5) * inv;
  write_sky_and_view(out, {view_x, 1.0, 1.0 - 1.0 / double(size << 1)},
                     {view_x, -1.0, -1.0 - 1.0 / double(size << 1)}, {0.2, 1.0, 0.0}, 0.0, 60.0);
  const Coord lights[6] = {{2.0, 0.5, 0.5},  {-1.0, 0.5, 0.5}, {0.5, 2.0, 0.5},
                           {0.5, -1.0, 0.5}, {0.5, 0.5, 2.0},  {0.5, 0.5, -1.0}};
  for (const Coord& l : lights) out.light(l);

  for (int x = 0; x <= size; ++x) {
    const double x0 = double(x) / double(size);
    for (int y = 0; y <= size; ++y) {
      const double y0 = double(y) / double(size);
      for (int z = 0; z <= size; ++z) {
        const double z0 = double(z) / double(size);
        out.surface(kSphere);
        out.sphere({x0, y0, z0, sphere_r});
        if (x != size) {
          out.surface(kRod[0]);
          out.cone({x0 + delta, y0, z0, rod_r}, {x0 + inv - delta, y0, z0, rod_r});
        }
        if (y != size) {
          out.surface(kRod[1]);
          out.cone({x0, y0 + delta, z0, rod_r}, {x0, y0 + inv - delta, z0, rod_r});
        }
        if (z != size) {
          out.surface(kRod[2]);
          out.cone({x0, y0, z0 + delta, rod_r}, {x0, y0, z0 + inv - delta, rod_r});
        }
      }
    }
  }
}

}  // namespace rayfarm::spd
