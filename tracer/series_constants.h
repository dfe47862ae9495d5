// The series coefficients of portable_math.h's exp2 and log2, 1/k and 1/k!,
// each rounded once at compile time: the same constants in the scalar
// functions and in the SIMD lanes that repeat them (simd/pow_lanes.h).
// Data only, so the kernels' units, compiled for other ISAs, may include it.
#pragma once

namespace rayfarm::detail {

struct SeriesConstants {
  double inverse[20] = {};
  double inverse_factorial[14] = {};
  constexpr SeriesConstants() {
    for (int k = 1; k < 20; ++k) inverse[k] = 1.0 / k;
    double f = 1;
    for (int k = 0; k < 14; ++k) {
      if (k > 0) f *= k;
      inverse_factorial[k] = 1.0 / f;
    }
  }
};
inline constexpr SeriesConstants kSeries{};

}  // namespace rayfarm::detail
