// The pixel's last step (tracer/pixel_estimate.h): NaN and Inf samples from the
// integrator are counted before the stored mean is made finite, with the
// functions the Renderer uses.
#include <doctest/doctest.h>

#include <cmath>
#include <limits>

#include "tracer/adaptive_sampling.h"
#include "tracer/pixel_estimate.h"

using namespace rayfarm;

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

}  // namespace

TEST_CASE("pixel_estimate: finite samples count nothing and their mean is stored as it is") {
  const Vec3 samples[4] = {{0.1, 0.5, 0.9}, {0.5, 0.5, 0.5}, {0.5, 0.5, 0.5}, {0.5, 0.5, 0.5}};
  RayStats stats;
  count_non_finite(samples, 4, stats);
  CHECK(stats.non_finite == 0);
  float out[3];
  store_mean(grid_mean(samples, 4), out);
  CHECK(out[0] == doctest::Approx((0.1 + 3 * 0.5) / 4));
  CHECK(out[1] == doctest::Approx(0.5));
  CHECK(out[2] == doctest::Approx((0.9 + 3 * 0.5) / 4));
}

TEST_CASE("pixel_estimate: a NaN or Inf sample is counted once and only its channel is stored as 0") {
  for (const Vec3 bad : {Vec3{kNaN, 0.5, 0.5}, Vec3{0.5, kInf, 0.5}, Vec3{0.5, 0.5, -kInf}}) {
    CAPTURE(bad.x);
    CAPTURE(bad.y);
    CAPTURE(bad.z);
    Vec3 samples[9];
    for (Vec3& v : samples) v = {0.5, 0.5, 0.5};
    samples[4] = bad;
    RayStats stats;
    count_non_finite(samples, 9, stats);
    CHECK(stats.non_finite == 1);
    float out[3];
    store_mean(grid_mean(samples, 9), out);
    for (int c = 0; c < 3; ++c) CHECK(out[c] == (std::isfinite(bad[c]) ? 0.5f : 0.0f));
  }
}

TEST_CASE("pixel_estimate: a finite mean past float's range is stored as the largest float, not Inf") {
  const Vec3 samples[1] = {{1e48, -1e48, 3e38}};
  RayStats stats;
  count_non_finite(samples, 1, stats);
  CHECK(stats.non_finite == 0);
  float out[3];
  store_mean(grid_mean(samples, 1), out);
  CHECK(out[0] == std::numeric_limits<float>::max());
  CHECK(out[1] == -std::numeric_limits<float>::max());
  CHECK(out[2] == doctest::Approx(3e38));
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
