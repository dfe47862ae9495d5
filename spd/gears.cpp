// gears: a cube of size^3 meshed gears above a reflective ground. Each gear has
// two concave 144-vertex faces and 144 side quads; one in five gears is glass
// (refraction), neighbours are turned half a tooth so they mesh. 5 lights.

#include <algorithm>
#include <cmath>
#include <vector>

#include "spd/generators.h"

namespace rayfarm::spd {
namespace {

constexpr int kTeeth = 36;                 // a multiple of 4
constexpr double kOuterEdgeRatio = 0.995;  // tips stop short of touching
constexpr double kInnerEdgeRatio = 0.9;    // tooth root radius
constexpr double kEdgeDiff = 1.0 - kInnerEdgeRatio;
constexpr double kDepthRatio = 0.1;  // thickness / width

// The 4 outline points of one tooth: two on the tip circle (+-0.19 of a tooth
// angle) and two on the root circle (0.3 and 0.7 of it).
void add_tooth(double gear_angle, double tooth_angle, const Coord& center, const Coord& outer,
               const Coord& inner, Coord* pts) {
  const double angles[4] = {gear_angle - 0.19 * tooth_angle, gear_angle + 0.19 * tooth_angle,
                            gear_angle + 0.3 * tooth_angle, gear_angle + 0.7 * tooth_angle};
  for (int i = 0; i < 4; ++i) {
    const Coord& radius_pt = i < 2 ? outer : inner;
    pts[i] = add3(transform_vector(radius_pt, rotate_matrix(Axis::Z, angles[i])), center);
  }
}

// Face outline of 4 * kTeeth points. `direction` -1 runs the other way round,
// so the bottom face winds opposite to the top one.
void gear_outline(double offset_angle, double direction, const Coord& center, const Coord& outer,
                  const Coord& inner, std::vector<Coord>& pts) {
  const double tooth_angle = 2.0 * kPi / double(kTeeth);
  for (int t = 0; t < kTeeth; ++t) {
    const double step = 2.0 * kPi * double(t) / double(kTeeth);
    const double gear_angle = direction > 0 ? offset_angle + step : offset_angle - step;
    add_tooth(gear_angle, direction * tooth_angle, center, outer, inner, &pts[4 * t]);
  }
}

void write_gear(const Coord& center, double offset_angle, double outer_radius, double inner_radius,
                double thickness, NffWriter& out) {
  std::vector<Coord> pts(4 * kTeeth);
  Coord outer = {outer_radius, 0.0, 0.0, 0.0};
  Coord inner = {inner_radius, 0.0, 0.0, 0.0};
  gear_outline(offset_angle, 1.0, center, outer, inner, pts);
  out.polygon(pts.data(), 4 * kTeeth);

  for (int i = 0; i < 4 * kTeeth; ++i) {
    const Coord& a = pts[i];
    const Coord& b = pts[(i + 1) % (4 * kTeeth)];
    Coord side[4] = {a, a, b, b};
    side[1].z -= thickness;
    side[2].z -= thickness;
    out.polygon(side, 4);
  }

  outer.z = inner.z = -thickness;
  gear_outline(offset_angle, -1.0, center, outer, inner, pts);
  out.polygon(pts.data(), 4 * kTeeth);
}

double fraction(double v) { return v - static_cast<int>(v); }

// Deterministic "pseudo-random" colour per grid cell, brightest channel = 1.
Surface gear_surface(int ix, int iy, int iz) {
  double c[3] = {0.01 + fraction(double(ix * 3 + iy * 2 + iz + 1) * 5.0 / 7.0),
                 0.01 + fraction(double(iy * 3 + iz * 2 + ix + 1) * 3.0 / 7.0),
                 0.01 + fraction(double(iz * 3 + ix * 2 + iy + 1) * 2.0 / 7.0)};
  const double scale = std::max(std::max(c[0], c[1]), c[2]);
  for (double& v : c) v /= scale;
  if ((ix * 4 + iy * 2 + iz) % 5 == 0)  // glass
    return {c[0], c[1], c[2], /*kd*/ 0.2, /*ks*/ 0.0, /*phong*/ 0.0, /*kt*/ 0.8, /*ior*/ 1.1};
  return {c[0], c[1], c[2], /*kd*/ 1.0, /*ks*/ 0.0, /*phong*/ 0.0, /*kt*/ 0.0, /*ior*/ 0.0};
}

}  // namespace

void write_gears(int size, NffWriter& out) {
  write_sky_and_view(out, {-1.1, -2.1, 2.6}, {0.0, 0.0, 0.0}, {0.0, 0.0, 1.0}, 1.0);
  out.light({2.0, 4.0, 4.0});
  out.light({-2.0, 4.0, 3.0});
  out.light({2.0, -2.5, 2.5});
  out.light({-1.0, -4.0, 2.0});
  out.light({-1.111, -2.121, 2.626});  // just behind the eye

  out.surface({1.0, 0.85, 0.7, /*kd*/ 0.3, /*ks*/ 0.6, /*phong*/ 37.0, /*kt*/ 0.0, /*ior*/ 0.0});
  const Coord ground[4] = {
      {2.0, 2.0, 0.0, 0.0}, {-2.0, 2.0, 0.0, 0.0}, {-2.0, -2.0, 0.0, 0.0}, {2.0, -2.0, 0.0, 0.0}};
  out.polygon(ground, 4);

  // Gears of radius R overlap by kEdgeDiff * R / 2 so their teeth interleave
  // while the whole row spans [-1, 1].
  const double outer_radius = 1.0 / (double(size) - double(size - 1) * kEdgeDiff / 2.0);
  const double first_xy = -1.0 + outer_radius;
  const double step_xy = outer_radius * (2.0 - kEdgeDiff);
  const double step_z = -1.0 / double(size);
  const double thickness = std::min(kDepthRatio, 1.0 / (2.0 * double(size)));

  Coord center;
  for (int iz = 0; iz < size; ++iz) {
    center.z = 1.0 + double(iz) * step_z;
    for (int iy = 0; iy < size; ++iy) {
      center.y = first_xy + double(iy) * step_xy;
      for (int ix = 0; ix < size; ++ix) {
        center.x = first_xy + double(ix) * step_xy;
        out.surface(gear_surface(ix, iy, iz));
        // Half a tooth's turn on alternate gears so neighbours mesh.
        const double angle = kPi * double((ix + iy + iz) % 2) / double(kTeeth);
        write_gear(center, angle, kOuterEdgeRatio * outer_radius, (1.0 - kEdgeDiff) * outer_radius,
                   thickness, out);
      }
    }
  }
}

}  // namespace rayfarm::spd
