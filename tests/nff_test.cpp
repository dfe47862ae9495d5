// NFF reader tests: every directive, the degenerate-geometry warnings, a table
// of malformed inputs with their exact messages, and the 15 SPD reference files
// with the primitive counts of spd/README.md section 5.
#include <doctest/doctest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <random>
#include <string>
#include <vector>

#include "tests/test_files.h"
#include "tests/test_paths.h"
#include "tracer/error.h"
#include "tracer/nff_reader.h"

using namespace rayfarm;

namespace {

// Lines 1-7: a valid view. Entities in the tests start on line 8.
const std::string kView =
    "v\nfrom 0 0 5\nat 0 0 0\nup 0 1 0\nangle 45\nhither 1\nresolution 64 48\n";

std::string error_of(const std::string& text) {
  try {
    parse_nff(text, "t.nff");
  } catch (const InputError& e) {
    return e.what();
  }
  return "(no error)";
}

}  // namespace

TEST_CASE("nff: view and background") {
  const Scene s = parse_nff("b 0.1 0.2 0.3\n" + kView, "t.nff");
  CHECK(s.background == Vec3{0.1, 0.2, 0.3});
  CHECK(s.camera.from == Vec3{0, 0, 5});
  CHECK(s.camera.at == Vec3{0, 0, 0});
  CHECK(s.camera.up == Vec3{0, 1, 0});
  CHECK(s.camera.angle_deg == 45);
  CHECK(s.camera.hither == 1);
  CHECK(s.camera.width == 64);
  CHECK(s.camera.height == 48);
  CHECK(s.primitive_count() == 0);
  CHECK(s.warnings.empty());
}

TEST_CASE("nff: every directive") {
  const Scene s = parse_nff(kView +
                                "l 1 2 3\n"
                                "l 4 5 6 0.5 0.25 1\n"
                                "f 1 0.5 0 0.7 0.3 10 0.2 1.5\n"
                                "s 1 2 3 0.5\n"
                                "c 0 0 0 1 0 1 0 0.5\n"
                                "p 3\n0 0 0\n1 0 0\n0 1 0\n"
                                "pp 3\n0 0 1 0 0 2\n1 0 1 0 0 1\n0 1 1 0 1 1\n",
                            "t.nff");
  REQUIRE(s.lights.size() == 2);
  CHECK(s.lights[0].position == Vec3{1, 2, 3});
  CHECK(s.lights[0].color == Vec3{1, 1, 1});
  CHECK(s.lights[1].position == Vec3{4, 5, 6});
  CHECK(s.lights[1].color == Vec3{0.5, 0.25, 1});
  REQUIRE(s.materials.size() == 1);
  const Material& m = s.materials[0];
  CHECK(m.color == Vec3{1, 0.5, 0});
  CHECK(m.kd == 0.7);
  CHECK(m.ks == 0.3);
  CHECK(m.shine == 10);
  CHECK(m.transmittance == 0.2);
  CHECK(m.ior == 1.5);
  REQUIRE(s.spheres.size() == 1);
  CHECK(s.spheres[0].center == Vec3{1, 2, 3});
  CHECK(s.spheres[0].radius == 0.5);
  REQUIRE(s.cones.size() == 1);
  CHECK(s.cones[0].base == Vec3{0, 0, 0});
  CHECK(s.cones[0].base_radius == 1);
  CHECK(s.cones[0].apex == Vec3{0, 1, 0});
  CHECK(s.cones[0].apex_radius == 0.5);
  REQUIRE(s.polygons.size() == 2);
  CHECK(s.polygons[0].first == 0);
  CHECK(s.polygons[0].count == 3);
  CHECK_FALSE(s.polygons[0].has_normals);
  CHECK(s.polygons[1].first == 3);
  CHECK(s.polygons[1].has_normals);
  REQUIRE(s.vertices.size() == 6);
  CHECK(s.vertices[4] == Vec3{1, 0, 1});
  // Normals are as long as the vertices, zero for the plain polygon and
  // normalised for the patch.
  REQUIRE(s.normals.size() == 6);
  CHECK(s.normals[0] == Vec3{0, 0, 0});
  CHECK(s.normals[3] == Vec3{0, 0, 1});
  CHECK(s.normals[5].y == doctest::Approx(std::sqrt(0.5)));
  CHECK(s.primitive_count() == 4);
  for (const Sphere& sp : s.spheres) CHECK(sp.material == 0);
  CHECK(s.warnings.empty());
}

TEST_CASE("nff: multi-line cone, comments, CRLF and geometry before the view") {
  const Scene s = parse_nff(
      "# a comment line\r\n"
      "s 0 0 0 1   # trailing comment\r\n"
      "c\r\n0 0 0 1\r\n0 2 0 1#glued comment\r\n" +
          kView + "p 3 # count\n0 0 0\n1 0 0 # vertex\n0 1 0\n",
      "t.nff");
  CHECK(s.spheres.size() == 1);
  REQUIRE(s.cones.size() == 1);
  CHECK(s.cones[0].apex == Vec3{0, 2, 0});
  CHECK(s.cones[0].apex_radius == 1);
  CHECK(s.polygons.size() == 1);
  CHECK(s.camera.width == 64);
}

TEST_CASE("nff: lone CR line ends (classic Mac OS) end comments and count lines") {
  // A comment ran on to the end of the file, silently dropping what followed,
  // and every error was reported on line 1.
  std::string view = kView;
  for (char& c : view)
    if (c == '\n') c = '\r';
  const Scene s = parse_nff(view + "s -1 0 0 1\r# second sphere\rs 1 0 0 1\rl 1 2 3\rs 0 0 0 0.5\r", "t.nff");
  CHECK(s.spheres.size() == 3);
  REQUIRE(s.lights.size() == 1);
  CHECK(s.lights[0].color == Vec3{1, 1, 1});
  // The colour of an `l` is read only from its own line.
  CHECK(error_of(view + "l 1 2 3\r0 1 0\r") ==
        "t.nff:9: a number, \"0\", where a keyword belongs (b, v, l, f, c, s, p or pp): more numbers than the entry "
        "before it takes?");
  CHECK(error_of(view + "s 0 0 0 1\r\rx\r") ==
        "t.nff:10: unknown keyword \"x\" (expected b, v, l, f, c, s, p or pp)");
  CHECK(error_of(view + "s 0 0 0 1\r\n\r\nx\r\n") ==
        "t.nff:10: unknown keyword \"x\" (expected b, v, l, f, c, s, p or pp)");
}

TEST_CASE("nff: a leading UTF-8 byte-order mark is skipped, and lines keep their numbers") {
  // As some Windows editors save: it failed as an unknown keyword "???b".
  const std::string bom = "\xEF\xBB\xBF";
  const Scene s = parse_nff(bom + "b 0.5 0 0\n" + kView + "s 0 0 0 1\n", "t.nff");
  CHECK(s.background == Vec3{0.5, 0, 0});
  CHECK(s.spheres.size() == 1);
  CHECK(parse_nff(bom + "# comment first\n" + kView, "t.nff").camera.width == 64);
  CHECK(error_of(bom + kView + "s 0 0\n") == "t.nff:8: expected 4 numbers after 's' (x y z radius), found end of file");
  // Only at the start: elsewhere those bytes are what they always were, quoted as written.
  CHECK(error_of(kView + bom + "s 0 0 0 1\n") ==
        "t.nff:8: unknown keyword \"" + bom + "s\" (expected b, v, l, f, c, s, p or pp)");
}

TEST_CASE("nff: a token is quoted as written, UTF-8 and all, its control characters left to the printer to escape") {
  // Every byte past ASCII was '?': "1\u00e9\u00e9" read "1????".
  CHECK(error_of(kView + "s 0 0 0 1\xc3\xa9\xc3\xa9\n") ==
        "t.nff:8: expected 4 numbers after 's' (x y z radius), found \"1\xc3\xa9\xc3\xa9\"");
  // Escaped here as well, they were escaped twice where the message is
  // printed (the whole of it, the file's name too): "\\x1b" on the terminal.
  CHECK(error_of(kView + "sph\xc3\xa8re\x1b[2J 0 0 0 1\n") ==
        "t.nff:8: unknown keyword \"sph\xc3\xa8re\x1b[2J\" (expected b, v, l, f, c, s, p or pp)");
  CHECK(error_of(kView + "sc\xe8ne 1\n") ==  // Latin-1
        "t.nff:8: unknown keyword \"sc\xe8ne\" (expected b, v, l, f, c, s, p or pp)");
  // A NUL would end the message (what() is a C string): it is U+FFFD.
  CHECK(error_of(kView + std::string("a\0b 1\n", 6)) ==
        "t.nff:8: unknown keyword \"a\xef\xbf\xbd" "b\" (expected b, v, l, f, c, s, p or pp)");
  // Cut at 40 bytes between characters, never inside one.
  std::string long_token = "x";
  for (int i = 0; i < 30; ++i) long_token += "\xc3\xa9";
  CHECK(error_of(kView + long_token + "\n") ==
        "t.nff:8: unknown keyword \"" + long_token.substr(0, 39) + "...\" (expected b, v, l, f, c, s, p or pp)");
}

TEST_CASE("nff: light colour is read only from the same line") {
  const Scene s = parse_nff(kView + "l 1 2 3 # 0.5 0.5 0.5\nl 1 2 3\ns 0 0 0 1\nl -1 -2 -3 0 1 0\n", "t.nff");
  REQUIRE(s.lights.size() == 3);
  CHECK(s.lights[0].color == Vec3{1, 1, 1});
  CHECK(s.lights[1].color == Vec3{1, 1, 1});
  CHECK(s.lights[2].color == Vec3{0, 1, 0});
  CHECK(s.spheres.size() == 1);
}

TEST_CASE("nff: materials apply until the next f, with a default before the first") {
  const Scene s = parse_nff(kView +
                                "s 0 0 0 1\n"
                                "f 1 0 0 1 0 0 0 0\ns 1 0 0 1\ns 2 0 0 1\n"
                                "f 0 1 0 1 0 0 0 0\np 3\n0 0 0\n1 0 0\n0 1 0\n",
                            "t.nff");
  REQUIRE(s.materials.size() == 3);
  CHECK(s.materials[0].color == Vec3{1, 1, 1});  // default: white, Kd 1
  CHECK(s.materials[0].kd == 1);
  CHECK(s.spheres[0].material == 0);
  CHECK(s.spheres[1].material == 1);
  CHECK(s.spheres[2].material == 1);
  CHECK(s.polygons[0].material == 2);
  CHECK(s.normals.empty());  // no patch, no normals
}

TEST_CASE("nff: degenerate geometry is skipped or repaired with a warning") {
  const Scene s = parse_nff(kView +
                                "s 0 0 0 0\n"                            // 8
                                "c 0 0 0 0 0 1 0 0\n"                    // 9
                                "c 1 1 1 1 1 1 1 0.5\n"                  // 10
                                "p 3\n0 0 0\n1 1 1\n2 2 2\n"             // 11
                                "p 5\n0 0 0\n0 0 0\n1 0 0\n1 1 0\n0 0 0\n"  // 15
                                "pp 3\n0 0 0 0 0 0\n1 0 0 0 0 1\n0 1 0 0 0 1\n"  // 21
                                "p 4\n0 0 0\n1 1 0\n1 0 0\n0 1 0\n",   // 25: a bow tie
                            "t.nff");
  CHECK(s.spheres.empty());
  CHECK(s.cones.empty());
  REQUIRE(s.polygons.size() == 2);
  CHECK(s.polygons[0].count == 3);  // the repeated vertices are gone
  CHECK(s.vertices[2] == Vec3{1, 1, 0});
  CHECK(s.normals[3] == Vec3{0, 0, 1});  // the face normal of the patch
  const std::vector<std::string> expected{
      "t.nff:8: skipped sphere with zero radius",
      "t.nff:9: skipped cone with both radii 0",
      "t.nff:10: skipped cone with base == apex",
      "t.nff:11: skipped polygon with zero area (vertices in a line, or crossing edges whose loops cancel)",
      "t.nff:15: removed 2 repeated polygon vertices",
      "t.nff:21: zero-length normal of vertex 1 replaced by the face normal",
      "t.nff:25: skipped polygon with zero area (vertices in a line, or crossing edges whose loops cancel)",
  };
  CHECK(s.warnings == expected);
}

TEST_CASE("nff: warnings beyond 50 are counted, not listed") {
  std::string text = kView;
  for (int i = 0; i < 60; ++i) text += "s 0 0 0 0\n";
  const Scene s = parse_nff(text, "t.nff");
  REQUIRE(s.warnings.size() == 51);
  CHECK(s.warnings.back() == "t.nff: 10 more warnings like these were not listed");
}

TEST_CASE("nff: malformed input gives the place and what was expected") {
  struct Case {
    std::string text;
    std::string message;
  };
  const std::string v1 = "v\nfrom 0 0 5\nat 0 0 0\nup 0 1 0\n";
  const std::vector<Case> cases{
      // Said of the file: it was "t.nff:1: expected a 'v' block (viewpoint) before end of file".
      {"", "t.nff: the file is empty; a scene needs a 'v' block (viewpoint) at least"},
      {"# just a comment\n", "t.nff: the file holds only comments and blank lines; a scene needs a 'v' block "
                             "(viewpoint) at least"},
      {" \n\t\r\n\n", "t.nff: the file holds only comments and blank lines; a scene needs a 'v' block "
                       "(viewpoint) at least"},
      {"b 0 0 0\ns 0 0 0 1\n", "t.nff:2: expected a 'v' block (viewpoint) before end of file"},
      {kView + "s 0 0 0\n", "t.nff:8: expected 4 numbers after 's' (x y z radius), found end of file"},
      {kView + "s 0 0 zero 1\n", "t.nff:8: expected 4 numbers after 's' (x y z radius), found \"zero\""},
      {kView + "s 0 0\n0 1,5\n", "t.nff:9: expected 4 numbers after 's' (x y z radius), found \"1,5\""},
      {kView + "s 0 0 nan 1\n", "t.nff:8: expected a finite number after 's' (x y z radius), found \"nan\""},
      {kView + "s 0 0 0 1e999\n", "t.nff:8: expected a finite number after 's' (x y z radius), found \"1e999\""},
      {kView + "c 0 0 0 inf 0 1 0 1\n",
       "t.nff:8: expected a finite number after 'c' (base x y z r, apex x y z r), found \"inf\""},
      {kView + "p 4\n0 0 0\n1 0 0\n1 1 0\ns 0 0 0 1\n",
       "t.nff:12: expected 3 numbers for vertex 4 of 'p 4', found \"s\""},
      {kView + "p 3\n0 0 0\n1 0 0\n", "t.nff:8: expected 3 numbers for vertex 3 of 'p 3', found end of file"},
      {kView + "p 2\n0 0 0\n1 0 0\n", "t.nff:8: expected a vertex count >= 3 after 'p', found 2"},
      {kView + "pp 0\n", "t.nff:8: expected a vertex count >= 3 after 'pp', found 0"},
      {kView + "p x\n", "t.nff:8: expected a vertex count after 'p', found \"x\""},
      // Refused before its vertices are read, which could take hours to triangulate.
      {kView + "p 4097\n", "t.nff:8: 'p 4097': at most 4096 vertices to a polygon (split it into several)"},
      {kView + "pp 99999999\n", "t.nff:8: 'pp 99999999': at most 4096 vertices to a polygon (split it into several)"},
      {kView + "pp 3\n0 0 0\n1 0 0\n0 1 0\n",
       "t.nff:8: expected 6 numbers for vertex 2 of 'pp 3', found end of file"},
      {kView + "x 1 2 3\n", "t.nff:8: unknown keyword \"x\" (expected b, v, l, f, c, s, p or pp)"},
      // One number too many: it was called an unknown keyword "2".
      {kView + "s 0 0 0 1 2\n",
       "t.nff:8: a number, \"2\", where a keyword belongs (b, v, l, f, c, s, p or pp): more numbers than the entry "
       "before it takes?"},
      {kView + "p 3\n0 0 0\n1 0 0\n0 1 0\n1 1 0\n",
       "t.nff:12: a number, \"1\", where a keyword belongs (b, v, l, f, c, s, p or pp): more numbers than the entry "
       "before it takes?"},
      {kView + "s 0 0 0 -1\n",
       "t.nff:8: negative sphere radius -1 (inside-visible spheres are not supported)"},
      {kView + "c 0 0 0 -1 0 1 0 -1\n",
       "t.nff:8: negative cone radius (inside-visible cones are not supported)"},
      {kView + "f 1 1 1 1 0 0 0\ns 0 0 0 1\n",
       "t.nff:9: expected 8 numbers after 'f' (R G B Kd Ks Shine T ior), found \"s\""},
      {kView + "f 1 1 1 0.2 0 0 0.8 0\n", "t.nff:8: ior must be > 0 for a transmitting surface, found 0"},
      {kView + "f 1 1 1 1 0 -2 0 0\n", "t.nff:8: Shine must be >= 0, found -2"},
      // Out of the NFF document's ranges: these shaded with negative light.
      {kView + "f 1 -0.5 1 1 0 0 0 0\n", "t.nff:8: G must be between 0 and 1, found -0.5"},
      {kView + "f 1 1 1.5 1 0 0 0 0\n", "t.nff:8: B must be between 0 and 1, found 1.5"},
      {kView + "f 1 1 1 -1 0 0 0 0\n", "t.nff:8: Kd must be >= 0, found -1"},
      {kView + "f 1 1 1 1 -0.2 0 0 0\n", "t.nff:8: Ks must be >= 0, found -0.2"},
      {kView + "f 1 1 1 1 0 0 -0.5 1\n", "t.nff:8: T must be between 0 and 1, found -0.5"},
      {kView + "f 1 1 1 0 0 0 1.5 1.5\n", "t.nff:8: T must be between 0 and 1, found 1.5"},
      {"b 0.5 -1 0\n" + kView, "t.nff:1: background G must be between 0 and 1, found -1"},
      {"b 0.5 0 2\n" + kView, "t.nff:1: background B must be between 0 and 1, found 2"},
      {kView + "l 0 0 5 1 1 -0.5\n", "t.nff:8: light colour B must be >= 0, found -0.5"},
      {kView + "l 1 2 3 1 1\ns 0 0 0 1\n", "t.nff:9: expected 3 numbers for the colour of 'l', found \"s\""},
      {kView + "l 1 2\n", "t.nff:8: expected 3 numbers after 'l', found end of file"},
      {kView + kView, "t.nff:8: second 'v' block (the view is already set on line 1)"},
      {"v\nat 0 0 0\n", "t.nff:2: expected \"from\" in the 'v' block, found \"at\""},
      {"v\nfrom 0 0 5\nat 0 0 0\n", "t.nff:1: expected \"up\" in the 'v' block, found end of file"},
      {v1 + "hither 1\nangle 45\nresolution 64 48\n",
       "t.nff:5: expected \"angle\" in the 'v' block, found \"hither\""},
      {v1 + "angle 45\nhither 1\nresolution 0 48\n", "t.nff:7: resolution must be between 1 and 65536, found 0"},
      {v1 + "angle 45\nhither 1\nresolution 64 -5\n", "t.nff:7: resolution must be between 1 and 65536, found -5"},
      {v1 + "angle 45\nhither 1\nresolution 512.5 512\n",
       "t.nff:7: expected 2 integers after 'resolution', found \"512.5\""},
      {v1 + "angle 180\nhither 1\nresolution 64 48\n", "t.nff:5: angle must be in (0, 180) degrees, found 180"},
      {v1 + "angle 0\nhither 1\nresolution 64 48\n", "t.nff:5: angle must be in (0, 180) degrees, found 0"},
      {v1 + "angle 45\nhither -1\nresolution 64 48\n", "t.nff:6: hither must be >= 0, found -1"},
      {"v\nfrom 0 0 5\nat 0 0 5\nup 0 1 0\nangle 45\nhither 1\nresolution 64 48\n",
       "t.nff:3: 'from' and 'at' must differ"},
      {"v\nfrom 0 0 5\nat 0 0 0\nup 0 0 0\nangle 45\nhither 1\nresolution 64 48\n",
       "t.nff:4: 'up' must not be zero"},
      {"v\nfrom 0 0 5\nat 0 0 0\nup 0 0 -3\nangle 45\nhither 1\nresolution 64 48\n",
       "t.nff:4: 'up' must not be parallel to the viewing direction"},
      {"v\nfrom 0 0 1e-200\nat 0 0 0\nup 0 1 0\nangle 45\nhither 1\nresolution 64 48\n",
       "t.nff:3: 'from' and 'at' are too close together to give a viewing direction"},
      {"v\nfrom 0 0 5\nat 0 0 0\nup 0 1e-200 0\nangle 45\nhither 1\nresolution 64 48\n",
       "t.nff:4: 'up' is too short to give a direction"},
      {kView + "\x01\x02 1\n", "t.nff:8: unknown keyword \"\x01\x02\" (expected b, v, l, f, c, s, p or pp)"},
  };
  CHECK(cases.size() >= 15);
  for (const Case& c : cases) {
    CAPTURE(c.text);
    CHECK(error_of(c.text) == c.message);
  }
}

TEST_CASE("nff: numbers parse to the same bits as strtod") {
  // The reader has a fast path for plain decimals; it must agree exactly with
  // the C library for every form the SPD writes (%g) and a few it does not.
  std::mt19937_64 rng(42);
  std::uniform_real_distribution<double> mag(-12, 12);
  std::vector<std::string> numbers{"0", "-0", ".5", "5.", "+2.5", "1e-5", "1E3", "0.1", "0.3",
                                   "123456789012345", "0.1234567890123456789", "0.000000000000000000001234",
                                   "9007199254740993", "1e-400"};
  char buf[64];
  for (int i = 0; i < 3000; ++i) {
    const double v = std::pow(10.0, mag(rng)) * (i % 2 ? -1 : 1);
    std::snprintf(buf, sizeof buf, "%.*g", 1 + i % 17, v);
    numbers.push_back(buf);
    std::snprintf(buf, sizeof buf, "%.*f", i % 24, v);
    numbers.push_back(buf);
  }
  for (const std::string& n : numbers) {
    CAPTURE(n);
    // A light's position takes any number (a colour only [0, 1]).
    const Scene s = parse_nff(kView + "l " + n + " 0 0\n", "t.nff");
    const double expected = std::strtod(n.c_str(), nullptr);
    CHECK(std::memcmp(&s.lights.at(0).position.x, &expected, sizeof expected) == 0);
  }
}

TEST_CASE("nff: unreadable file names the path") {
  const std::string path = "/nonexistent/nope.nff";
  CHECK_THROWS_WITH_AS(read_nff_file(path), "/nonexistent/nope.nff: cannot open (No such file or directory)",
                       InputError);
  CHECK_THROWS_WITH_AS(read_nff_file("/"), "/: cannot read (Is a directory)", InputError);
}

TEST_CASE("nff: a scene file past the 256 MiB scene limit is refused, read no further than the limit") {
  // /dev/zero was read until the string could grow no more: std::bad_alloc.
  CHECK_THROWS_WITH_AS(read_nff_text("/dev/zero"), "/dev/zero: larger than the 256 MiB scene limit", InputError);
  // A regular file is judged by its size before any of it is read (sparse: no disk used).
  const std::string big = test::write_file(test::scratch_dir("nff-limit") / "big.nff", "");
  std::filesystem::resize_file(big, kMaxSceneBytes + 1);
  CHECK_THROWS_WITH_AS(read_nff_file(big), (big + ": larger than the 256 MiB scene limit").c_str(), InputError);
}

TEST_CASE("nff: the 15 SPD reference files parse with the documented counts") {
  struct Expected {
    const char* file;
    size_t spheres, cones, polygons, big_polygons, lights, materials;
  };
  const Expected table[] = {
      {"tetra-1", 0, 0, 4, 0, 1, 1},        {"tetra-2", 0, 0, 16, 0, 1, 1},
      {"tetra-6", 0, 0, 4096, 0, 1, 1},     {"balls-1", 10, 0, 1, 0, 3, 2},
      {"balls-2", 91, 0, 1, 0, 3, 2},       {"balls-4", 7381, 0, 1, 0, 3, 2},
      {"mount-1", 4, 0, 8, 0, 1, 2},        {"mount-2", 4, 0, 32, 0, 1, 2},
      {"mount-6", 4, 0, 8192, 0, 1, 2},     {"rings-1", 30, 30, 1, 0, 3, 7},
      {"rings-2", 150, 150, 1, 0, 3, 31},   {"rings-7", 4200, 4200, 1, 0, 3, 841},
      {"gears-1", 0, 0, 147, 2, 5, 2},      {"gears-2", 0, 0, 1169, 16, 5, 9},
      {"gears-4", 0, 0, 9345, 128, 5, 65},
  };
  const std::pair<const char*, size_t> paper[] = {
      {"tetra-6", 4096}, {"balls-4", 7382}, {"mount-6", 8196}, {"rings-7", 8401}, {"gears-4", 9345}};
  for (const Expected& e : table) {
    CAPTURE(e.file);
    // The paper sizes are the checked-in scenes/; the small sizes live in tests/data.
    const std::string stem = e.file;
    bool is_paper = false;
    for (const auto& [name, count] : paper) is_paper |= stem == name;
    const std::string path =
        is_paper ? test::paper_scene(stem.substr(0, stem.find('-'))) : test::spd_data(stem);
    const Scene s = read_nff_file(path);
    CHECK(s.spheres.size() == e.spheres);
    CHECK(s.cones.size() == e.cones);
    CHECK(s.polygons.size() == e.polygons);
    size_t big = 0;
    for (const Polygon& p : s.polygons) big += p.count == 144;
    CHECK(big == e.big_polygons);
    CHECK(s.lights.size() == e.lights);
    CHECK(s.materials.size() == e.materials);
    CHECK(s.warnings.empty());
    CHECK(s.normals.empty());
    CHECK(s.camera.width == 512);
    CHECK(s.camera.angle_deg == 45);
    CHECK(s.background == Vec3{0.078, 0.361, 0.753});
    for (const auto& [name, count] : paper)
      if (std::string(name) == e.file) CHECK(s.primitive_count() == count);
  }
}
