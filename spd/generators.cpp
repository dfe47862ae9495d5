// The generator registry and the scene opening shared by all SPD scenes.

#include "spd/generators.h"

#include <string>

#include "tracer/error.h"

namespace rayfarm::spd {

const std::vector<Generator>& generators() {
  // Maximum sizes keep a typo from writing hundreds of gigabytes: balls 7 is
  // already 228 MB (5.4 M spheres). mount stops at 7 because the original hash
  // shifts by (7 - size) bits, which is undefined in C for larger sizes.
  static const std::vector<Generator> all = {
      {"tetra", "Sierpinski tetrahedron of triangles; 81% background, 1 light", 6, 10, write_tetra},
      {"balls", "sphereflake: recursive mirror spheres over a floor, 3 lights", 4, 7, write_balls},
      {"mount", "fractal mountain with 4 glass spheres (refraction), 1 light", 6, 7, write_mount},
      {"rings", "pyramid of reflective dodecahedral rings of cylinders and spheres, 3 lights", 7,
       30, write_rings},
      {"gears", "cube of meshed gears with concave 144-gon faces, some glass, 5 lights", 4, 12,
       write_gears},
      // Extras, not in the paper.
      {"tree", "Aono & Kunii tree of cones and spheres on a field, 7 lights", 11, 18, write_tree},
      {"teapot", "Newell teapot as smooth triangles (pp) on a checkerboard, 2 lights", 6, 40,
       write_teapot},
      {"lattice", "cubic lattice of shiny spheres joined by matte rods, 6 lights", 12, 40,
       write_lattice},
      {"shells", "Pickover's sea shell of overlapping spheres, 1 light", 5, 12, write_shells},
      {"jacks", "recursive jacks (rods and balls) in octants, 1 light", 1, 6, write_jacks},
  };
  return all;
}

std::string generator_table() {
  std::string table;
  for (const Generator& g : generators()) {
    std::string line = "  " + std::string(g.name);
    line.resize(10, ' ');
    line += "default " + std::to_string(g.default_size);
    line.resize(21, ' ');
    line += "sizes 1.." + std::to_string(g.max_size);
    line.resize(34, ' ');
    table += line + g.summary + "\n";
  }
  return table;
}

const Generator& find_generator(std::string_view name) {
  std::string names;
  for (const Generator& g : generators()) {
    if (name == g.name) return g;
    names += names.empty() ? "" : ", ";
    names += g.name;
  }
  throw InputError("unknown SPD scene \"" + std::string(name) + "\" (valid: " + names + ")");
}

void check_size(const Generator& g, int size) {
  if (size < 1 || size > g.max_size)
    throw InputError("spd " + std::string(g.name) + ": size " + std::to_string(size) +
                     " out of range 1.." + std::to_string(g.max_size) + " (default " +
                     std::to_string(g.default_size) + ")");
}

void generate(std::string_view name, int size, std::ostream& out) {
  const Generator& g = find_generator(name);
  check_size(g, size);
  NffWriter writer(out);
  g.write(size, writer);
  writer.flush();
}

void write_sky_and_view(NffWriter& out, const Coord& from, const Coord& at, const Coord& up,
                        double hither, double angle) {
  out.background(0.078, 0.361, 0.753);
  View view;
  view.from = from;
  view.at = at;
  view.up = up;
  view.angle = angle;
  view.hither = hither;
  out.viewpoint(view);
}

}  // namespace rayfarm::spd
