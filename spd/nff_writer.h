// NffWriter: emits NFF entities exactly as Haines' SPD library writes them
// (every real with C "%g", one entity per line, `c` on a single line, polygon
// vertices one per line), streaming into a std::ostream through a small
// buffer so that multi-million-primitive scenes never sit in memory.
// Write failures (full disk, closed pipe) throw std::runtime_error.
#pragma once

#include <cstddef>
#include <ostream>
#include <string>

#include "spd/spd_math.h"

namespace rayfarm::spd {

// Camera block of the NFF `v` entity.
struct View {
  Coord from, at, up;
  double angle = 45.0;  // full field of view in degrees
  double hither = 1.0;
  int resx = 512, resy = 512;
};

// Surface description as the SPD library takes it. `phong_angle` is the
// half-angle in degrees at which the highlight falls to 50%; NFF stores the
// derived Phong exponent. The library's ambient and highlight-strength terms
// have no NFF field, so they are not represented here.
struct Surface {
  double r = 1.0, g = 1.0, b = 1.0;
  double kd = 1.0;           // diffuse
  double ks = 0.0;           // mirror reflection weight (NFF "Ks")
  double phong_angle = 0.0;  // degrees; 0 = no visible highlight
  double kt = 0.0;           // transmission
  double ior = 0.0;          // index of refraction (as written, also for opaque)
};

class NffWriter {
 public:
  explicit NffWriter(std::ostream& out);
  ~NffWriter();  // flushes; errors at this point are lost, so call flush()
  NffWriter(const NffWriter&) = delete;
  NffWriter& operator=(const NffWriter&) = delete;

  void comment(const std::string& text);
  void background(double r, double g, double b);
  void viewpoint(const View& view);
  void light(const Coord& position);
  void surface(const Surface& s);
  void sphere(const Coord& center_radius);          // w = radius
  void cone(const Coord& base, const Coord& apex);  // w = radii
  void polygon(const Coord* vertices, int count);
  void patch(const Coord* vertices, const Coord* normals, int count);

  // Writes everything buffered to the stream and throws if the stream failed.
  void flush();

  // Phong exponent for a highlight half-angle (degrees): ln(0.5) / ln(cos a),
  // with 0 -> 100000 ("no highlight") and >= 90 -> 1, as the SPD defines it.
  static double phong_exponent(double half_angle_degrees);

 private:
  void number(double v);        // " %g" (leading space)
  void first_number(double v);  // "%g"
  template <typename... T>
  void numbers(T... v) {
    (number(v), ...);
  }
  void text(const char* s);
  void integer(int v);
  void end_line();

  std::ostream& out_;
  std::string buf_;
};

}  // namespace rayfarm::spd
