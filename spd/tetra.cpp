// tetra: the recursive tetrahedral pyramid (a Sierpinski tetrahedron) that
// Glassner and Kay & Kajiya used; 4^size triangles, one red material, one
// light, and a view in which about 81% of the eye rays see the background.

#include <utility>

#include "spd/generators.h"

namespace rayfarm::spd {
namespace {

// The four cube corners whose sign product is +1, in x-major, y, z order:
// (-,-,+), (-,+,-), (+,-,-), (+,+,+).
template <typename Visit>
void for_each_tetra_corner(Visit visit) {
  for (int x = -1; x <= 1; x += 2)
    for (int y = -1; y <= 1; y += 2)
      for (int z = -1; z <= 1; z += 2)
        if (x * y * z == 1) visit(x, y, z);
}

// Leaf: the tetrahedron with centre c and half-size c.w as four triangles,
// faces (0,1,2), (3,2,1), (2,3,0), (1,0,3) so all wind the same way.
void write_tetrahedron(const Coord& c, NffWriter& out) {
  Coord corner[4];
  int n = 0;
  for_each_tetra_corner([&](int x, int y, int z) {
    corner[n++] = {c.x + double(x) * c.w, c.y + double(y) * c.w, c.z + double(z) * c.w, 0.0};
  });
  for (int face = 0; face < 4; ++face) {
    int order[3] = {face % 4, (face + 1) % 4, (face + 2) % 4};
    if (face % 2 == 1) std::swap(order[0], order[2]);
    const Coord tri[3] = {corner[order[0]], corner[order[1]], corner[order[2]]};
    out.polygon(tri, 3);
  }
}

void subdivide(int depth, const Coord& c, NffWriter& out) {
  if (depth <= 1) {
    write_tetrahedron(c, out);
    return;
  }
  for_each_tetra_corner([&](int x, int y, int z) {
    const Coord sub = {c.x + double(x) * c.w / 2.0, c.y + double(y) * c.w / 2.0,
                       c.z + double(z) * c.w / 2.0, c.w / 2.0};
    subdivide(depth - 1, sub, out);
  });
}

}  // namespace

void write_tetra(int size, NffWriter& out) {
  // Kay & Kajiya's view, transformed into this model's coordinates.
  write_sky_and_view(out, {1.022846, -3.177154, -2.174512}, {-0.004103, -0.004103, 0.216539},
                     {-0.816497, -0.816497, 0.816497}, 1.0);
  out.light({2.0, -18.0, -5.0});
  out.surface({1.0, 0.2, 0.2, /*kd*/ 1.0, /*ks*/ 0.0, /*phong*/ 0.0, /*kt*/ 0.0, /*ior*/ 0.0});
  subdivide(size, {0.0, 0.0, 0.0, 1.0}, out);
}

}  // namespace rayfarm::spd
