// Vec3: the small 3-vector used throughout the tracer, in double precision.
// Scene descriptions are kept in double so that far-from-origin scenes survive
// until the Embree scene is built camera-relative (see embree_scene.h); the hot
// path converts to float where Embree wants it.
#pragma once

#include <cmath>

namespace rayfarm {

struct Vec3 {
  double x = 0, y = 0, z = 0;

  constexpr Vec3() = default;
  constexpr Vec3(double x_, double y_, double z_) : x(x_), y(y_), z(z_) {}

  constexpr double operator[](int i) const { return i == 0 ? x : (i == 1 ? y : z); }
  constexpr Vec3 operator-() const { return {-x, -y, -z}; }
  constexpr Vec3& operator+=(const Vec3& o) { x += o.x; y += o.y; z += o.z; return *this; }
  constexpr Vec3& operator-=(const Vec3& o) { x -= o.x; y -= o.y; z -= o.z; return *this; }
  constexpr Vec3& operator*=(double s) { x *= s; y *= s; z *= s; return *this; }
};

constexpr Vec3 operator+(Vec3 a, const Vec3& b) { return a += b; }
constexpr Vec3 operator-(Vec3 a, const Vec3& b) { return a -= b; }
constexpr Vec3 operator*(Vec3 a, double s) { return a *= s; }
constexpr Vec3 operator*(double s, Vec3 a) { return a *= s; }
constexpr Vec3 operator/(Vec3 a, double s) { return a *= (1.0 / s); }
// Component-wise product, for colours.
constexpr Vec3 operator*(const Vec3& a, const Vec3& b) { return {a.x * b.x, a.y * b.y, a.z * b.z}; }
constexpr bool operator==(const Vec3& a, const Vec3& b) { return a.x == b.x && a.y == b.y && a.z == b.z; }
constexpr bool operator!=(const Vec3& a, const Vec3& b) { return !(a == b); }

constexpr double dot(const Vec3& a, const Vec3& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
// Lane i of a vector stored lane-major, as the SIMD lane kernels keep them:
// rows x, y and z of N lanes each (lane_kernels.h).
template <int N>
constexpr Vec3 lane_vec(const double (&rows)[3][N], int i) { return {rows[0][i], rows[1][i], rows[2][i]}; }
constexpr Vec3 cross(const Vec3& a, const Vec3& b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
inline double length(const Vec3& a) { return std::sqrt(dot(a, a)); }
// Returns `a` unchanged when its length is zero, so callers can test for that.
inline Vec3 normalize(const Vec3& a) {
  const double len = length(a);
  return len > 0 ? a / len : a;
}
// Room for N Vec3s that are written before they are read. An array of Vec3
// zeroes every element (the default member initialisers), which for the
// per-pixel sample buffers cost 2% of a render.
template <int N>
class Vec3Scratch {
 public:
  Vec3* data() { return reinterpret_cast<Vec3*>(bytes_); }
  Vec3& operator[](int i) { return data()[i]; }

 private:
  alignas(Vec3) unsigned char bytes_[N * sizeof(Vec3)];
};

inline bool is_finite(const Vec3& a) {
  return std::isfinite(a.x) && std::isfinite(a.y) && std::isfinite(a.z);
}

}  // namespace rayfarm
