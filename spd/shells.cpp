// shells: Pickover's sea shell (IEEE CG&A, November 1989): 180 * 2^size + 1
// spheres growing along a logarithmic spiral, heavily overlapping and many of
// them tiny: a pathological but realistic test. 1 light.

#include <cmath>

#include "spd/generators.h"

namespace rayfarm::spd {
namespace {

// Pickover's shape parameters at the SPD's defaults.
constexpr double kGamma = 1.0;  // radius divisor
constexpr double kBeta = -2.0;  // z = beta * r (alpha = 0 selects this form)
constexpr double kA = 0.15;     // spiral growth exponent
constexpr double kK = 1.0;      // relative size

}  // namespace

void write_shells(int size, NffWriter& out) {
  write_sky_and_view(out, {-6.0, -60.0, 35.0}, {0.0, 8.0, -15.0}, {0.0, 0.0, 1.0}, 0.5);
  out.light({-100.0, -100.0, 100.0});
  out.surface({1.0, 0.8, 0.4, /*kd*/ 0.8, /*ks*/ 0.2, /*phong*/ 10.0, /*kt*/ 0.0, /*ior*/ 1.0});

  const long steps = static_cast<long>(180.0 * std::pow(2.0, double(size)));
  // Three turns of the spiral: two thirds before angle 0, one third after.
  for (long i = -steps * 2 / 3; i <= steps / 3; ++i) {
    const double angle = 3.0 * 6.0 * kPi * double(i) / double(steps);
    const double r = kK * std::exp(kA * angle);
    out.sphere({r * std::sin(angle), r * std::cos(angle), kBeta * r, r / kGamma});
  }
}

}  // namespace rayfarm::spd
