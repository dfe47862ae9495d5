// Eye rays for the NFF pinhole camera. NFF's `angle` is the full field of view
// between the centres of the outermost pixel rows/columns, so the pixel pitch on
// the image plane at distance 1 is tan(angle/2) / ((n - 1) / 2). For non-square
// images the angle applies to the shorter side (pixels stay square). `up` is
// orthogonalised against the view direction. Rays are camera-relative: they
// start at the origin of the Embree scene, which sits at `from`. `hither` is
// not applied: NFF meant it for z-buffer renderers, eye rays start at the eye,
// and no SPD scene has geometry that close to it.
#pragma once

#include <algorithm>
#include <cmath>

#include "tracer/portable_math.h"
#include "tracer/scene.h"
#include "tracer/vec3.h"

namespace rayfarm {

class CameraModel {
 public:
  CameraModel(const Camera& camera, int width, int height) : width_(width), height_(height) {
    forward_ = normalize(camera.at - camera.from);
    if (dot(forward_, forward_) == 0) forward_ = {0, 0, -1};
    right_ = normalize(cross(forward_, camera.up));
    if (dot(right_, right_) < 0.5) {
      // `up` parallel to the view: any perpendicular keeps the image finite.
      right_ = normalize(cross(forward_, std::fabs(forward_.x) < 0.9 ? Vec3{1, 0, 0} : Vec3{0, 1, 0}));
    }
    up_ = cross(right_, forward_);
    const int n = std::min(width, height);
    const double kPi = 3.14159265358979323846;
    pitch_ = portable_tan(camera.angle_deg * kPi / 360.0) / (std::max(n - 1, 1) * 0.5);
  }

  // Direction (not normalised) through image position (px, py) in pixel units:
  // pixel (x, y) covers [x, x+1) x [y, y+1), row 0 at the top.
  Vec3 direction(double px, double py) const {
    const double sx = (px - 0.5 * width_) * pitch_;
    const double sy = (0.5 * height_ - py) * pitch_;
    return forward_ + sx * right_ + sy * up_;
  }

  // Where camera-relative point p appears: the image position (px, py)
  // whose direction() passes through it, when p lies in front of the eye
  // (false otherwise, and for a camera without a field of view).
  bool project(const Vec3& p, double& px, double& py) const {
    const double depth = dot(p, forward_);
    if (!(depth > 0) || !(pitch_ > 0)) return false;
    px = dot(p, right_) / (depth * pitch_) + 0.5 * width_;
    py = 0.5 * height_ - dot(p, up_) / (depth * pitch_);
    return std::isfinite(px) && std::isfinite(py);
  }

  const Vec3& forward() const { return forward_; }

 private:
  int width_, height_;
  Vec3 forward_, right_, up_;
  double pitch_ = 0;
};

}  // namespace rayfarm
