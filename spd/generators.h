// Registry of the Standard Procedural Database generators (Eric Haines' SPD):
// name -> default and maximum size factor -> a function streaming the scene
// as NFF. The five paper scenes (tetra, balls, mount, rings, gears) reproduce
// the original programs' output byte for byte (see scenes/README.md); the
// extras (tree, teapot, lattice, shells, jacks) follow the original programs
// step by step but are checked only against the SPD's primitive counts.
#pragma once

#include <ostream>
#include <string>
#include <string_view>
#include <vector>

#include "spd/nff_writer.h"

namespace rayfarm::spd {

struct Generator {
  const char* name;
  const char* summary;
  int default_size;  // the original program's built-in size factor
  int max_size;      // refuse larger: the output grows geometrically
  void (*write)(int size, NffWriter& out);
};

// All generators, paper scenes first, in a fixed order.
const std::vector<Generator>& generators();

// Throws InputError naming the valid generators if `name` is unknown.
const Generator& find_generator(std::string_view name);

// Throws InputError unless 1 <= size <= g.max_size.
void check_size(const Generator& g, int size);

// Checks the size (see check_size) and streams the scene.
void generate(std::string_view name, int size, std::ostream& out);

// One line per generator: "name  default N, sizes 1..M  summary".
std::string generator_table();

// The individual scenes (one file each).
void write_tetra(int size, NffWriter& out);
void write_balls(int size, NffWriter& out);
void write_mount(int size, NffWriter& out);
void write_rings(int size, NffWriter& out);
void write_gears(int size, NffWriter& out);
void write_tree(int size, NffWriter& out);
void write_lattice(int size, NffWriter& out);
void write_shells(int size, NffWriter& out);
void write_teapot(int size, NffWriter& out);
void write_jacks(int size, NffWriter& out);

// Shared opening of the SPD scenes: the "UNC sky blue" background and a
// 512x512 view (45 degrees in all paper scenes).
void write_sky_and_view(NffWriter& out, const Coord& from, const Coord& at, const Coord& up,
                        double hither, double angle = 45.0);

}  // namespace rayfarm::spd
