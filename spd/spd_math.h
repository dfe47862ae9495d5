// The small vector/matrix kit the SPD generators are written against: 4-component
// coordinates and 4x4 matrices applied to a ROW vector on the left (p' = p * M,
// translation in the bottom row), as in Haines' SPD library. Every routine keeps
// the library's exact order of floating-point operations, because the generated
// NFF is compared byte for byte with the original programs' output: reordering
// a sum, or dropping a "+ 0 * m" term, flips the last digit or the sign of a zero.
#pragma once

#include <cmath>

namespace rayfarm::spd {

// PI exactly as the SPD defines it (def.h), not M_PI: the text is the spec.
inline constexpr double kPi = 3.141592653589793;

// x, y, z and a fourth slot w: a radius for spheres and cone ends, a homogeneous
// coordinate for points, a scale factor for the sphereflake directions.
struct Coord {
  double x = 0.0, y = 0.0, z = 0.0, w = 0.0;
};

struct Matrix {
  double m[4][4] = {};
};

enum class Axis { X, Y, Z };

inline double dot(const Coord& a, const Coord& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }

inline Coord cross(const Coord& a, const Coord& b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x, 0.0};
}

inline Coord add3(const Coord& a, const Coord& b) { return {a.x + b.x, a.y + b.y, a.z + b.z, a.w}; }
inline Coord sub3(const Coord& a, const Coord& b) { return {a.x - b.x, a.y - b.y, a.z - b.z, a.w}; }

// Divides by the length only when it is positive (a zero vector stays zero).
inline double normalize(Coord& v) {
  const double len = std::sqrt(dot(v, v));
  if (len > 0.0) {
    v.x /= len;
    v.y /= len;
    v.z /= len;
  }
  return len;
}

inline Matrix identity_matrix() {
  Matrix mx;
  for (int i = 0; i < 4; ++i) mx.m[i][i] = 1.0;
  return mx;
}

// Rotation about a coordinate axis, laid out for row vectors: about Z,
// (x, y) -> (x cos - y sin, x sin + y cos).
inline Matrix rotate_matrix(Axis axis, double angle) {
  Matrix mx;
  const double c = std::cos(angle);
  const double s = std::sin(angle);
  switch (axis) {
    case Axis::X:
      mx.m[0][0] = 1.0;
      mx.m[1][1] = c;
      mx.m[2][2] = c;
      mx.m[1][2] = s;
      mx.m[2][1] = -s;
      break;
    case Axis::Y:
      mx.m[1][1] = 1.0;
      mx.m[0][0] = c;
      mx.m[2][2] = c;
      mx.m[2][0] = s;
      mx.m[0][2] = -s;
      break;
    case Axis::Z:
      mx.m[2][2] = 1.0;
      mx.m[0][0] = c;
      mx.m[1][1] = c;
      mx.m[0][1] = s;
      mx.m[1][0] = -s;
      break;
  }
  mx.m[3][3] = 1.0;
  return mx;
}

// Rotation by `angle` about the unit axis (a, b, c): the Rodrigues matrix for
// row vectors, e.g. [0][1] = ab(1 - cos) + c sin.
inline Matrix axis_rotate_matrix(const Coord& axis, double angle) {
  Matrix mx;
  const double c = std::cos(angle);
  const double s = std::sin(angle);
  const double t = 1.0 - c;
  const double ax = axis.x, ay = axis.y, az = axis.z;
  mx.m[0][0] = ax * ax + (1.0 - ax * ax) * c;
  mx.m[0][1] = ax * ay * t + az * s;
  mx.m[0][2] = ax * az * t - ay * s;
  mx.m[1][0] = ax * ay * t - az * s;
  mx.m[1][1] = ay * ay + (1.0 - ay * ay) * c;
  mx.m[1][2] = ay * az * t + ax * s;
  mx.m[2][0] = ax * az * t + ay * s;
  mx.m[2][1] = ay * az * t - ax * s;
  mx.m[2][2] = az * az + (1.0 - az * az) * c;
  mx.m[3][3] = 1.0;
  return mx;
}

// Direction: the upper 3x3 only. Keeps v.w.
inline Coord transform_vector(const Coord& v, const Matrix& mx) {
  const auto& m = mx.m;
  return {v.x * m[0][0] + v.y * m[1][0] + v.z * m[2][0],
          v.x * m[0][1] + v.y * m[1][1] + v.z * m[2][1],
          v.x * m[0][2] + v.y * m[1][2] + v.z * m[2][2], v.w};
}

// Point: 3x3 plus the translation row. Keeps v.w.
inline Coord transform_point(const Coord& v, const Matrix& mx) {
  const auto& m = mx.m;
  return {v.x * m[0][0] + v.y * m[1][0] + v.z * m[2][0] + m[3][0],
          v.x * m[0][1] + v.y * m[1][1] + v.z * m[2][1] + m[3][1],
          v.x * m[0][2] + v.y * m[1][2] + v.z * m[2][2] + m[3][2], v.w};
}

// Full homogeneous product of all four components. The "+ w * m[3][j]" terms
// are kept even when they are zero: -0 + 0 is +0, and the files show it.
inline Coord transform_coord(const Coord& v, const Matrix& mx) {
  const auto& m = mx.m;
  return {v.x * m[0][0] + v.y * m[1][0] + v.z * m[2][0] + v.w * m[3][0],
          v.x * m[0][1] + v.y * m[1][1] + v.z * m[2][1] + v.w * m[3][1],
          v.x * m[0][2] + v.y * m[1][2] + v.z * m[2][2] + v.w * m[3][2],
          v.x * m[0][3] + v.y * m[1][3] + v.z * m[2][3] + v.w * m[3][3]};
}

inline Matrix multiply(const Matrix& a, const Matrix& b) {
  Matrix r;
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j)
      r.m[i][j] = a.m[i][0] * b.m[0][j] + a.m[i][1] * b.m[1][j] + a.m[i][2] * b.m[2][j] +
                  a.m[i][3] * b.m[3][j];
  return r;
}

inline Matrix translate_matrix(const Coord& v) {
  Matrix mx = identity_matrix();
  mx.m[3][0] = v.x;
  mx.m[3][1] = v.y;
  mx.m[3][2] = v.z;
  return mx;
}

inline Matrix scale_matrix(const Coord& v) {
  Matrix mx;
  mx.m[0][0] = v.x;
  mx.m[1][1] = v.y;
  mx.m[2][2] = v.z;
  mx.m[3][3] = 1.0;
  return mx;
}

}  // namespace rayfarm::spd
