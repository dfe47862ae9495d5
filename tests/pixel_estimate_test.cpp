// The pixel's last step (tracer/pixel_estimate.h): NaN and Inf samples from the
// integrator are counted before the stored mean is made finite. The shader is
// injected, so a deliberately broken sample can be fed through the same code
// the Renderer uses.
#include <doctest/doctest.h>

#include <cmath>
#include <limits>

#include "tracer/pixel_estimate.h"

using namespace rayfarm;

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

// A shader returning `bad` for one cell and 0.5 grey elsewhere.
struct OneBadCell {
  int cell;
  Vec3 bad;
  void operator()(const int* cells, int count, Vec3* rgb) const {
    for (int i = 0; i < count; ++i) rgb[i] = cells[i] == cell ? bad : Vec3{0.5, 0.5, 0.5};
  }
};

}  // namespace

TEST_CASE("pixel_estimate: finite samples give their mean and count nothing") {
  RayStats stats;
  float out[3];
  estimate_pixel(2, 0, OneBadCell{0, {0.1, 0.5, 0.9}}, stats, out);
  CHECK(stats.non_finite == 0);
  CHECK(out[0] == doctest::Approx((0.1 + 3 * 0.5) / 4));
  CHECK(out[1] == doctest::Approx(0.5));
  CHECK(out[2] == doctest::Approx((0.9 + 3 * 0.5) / 4));
}

TEST_CASE("pixel_estimate: a NaN or Inf sample is counted and only its channel is stored as 0") {
  for (const Vec3 bad : {Vec3{kNaN, 0.5, 0.5}, Vec3{0.5, kInf, 0.5}, Vec3{0.5, 0.5, -kInf}}) {
    CAPTURE(bad.x);
    CAPTURE(bad.y);
    CAPTURE(bad.z);
    RayStats stats;
    float out[3];
    estimate_pixel(3, 0, OneBadCell{4, bad}, stats, out);
    CHECK(stats.non_finite == 1);
    for (int c = 0; c < 3; ++c) CHECK(out[c] == (std::isfinite(bad[c]) ? 0.5f : 0.0f));
  }
}

TEST_CASE("pixel_estimate: adaptive sampling counts a bad coarse sample once") {
  // With k = 3 and a threshold the four corners are traced first; whether or
  // not the contrast test then refines, a corner is reused, never traced
  // again, so the bad one is counted once.
  RayStats stats;
  float out[3];
  int traced_cells = 0;
  const OneBadCell shader{0, {kNaN, kNaN, kNaN}};
  estimate_pixel(
      3, 0.1,
      [&](const int* cells, int count, Vec3* rgb) {
        traced_cells += count;
        shader(cells, count, rgb);
      },
      stats, out);
  CHECK(traced_cells <= 9);
  CHECK(stats.non_finite == 1);
  for (float v : out) CHECK(v == 0.0f);
}

TEST_CASE("pixel_estimate: non-finite counts add up across RayStats") {
  RayStats a, b;
  a.non_finite = 2;
  b.non_finite = 3;
  b.eye = 7;
  a += b;
  CHECK(a.non_finite == 5);
  CHECK(a.total() == 7);  // not a ray kind
}
