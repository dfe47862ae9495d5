// Adaptive supersampling (tracer/adaptive_sampling.h): Rayshade's contrast,
// the neighbourhood rule on the corner lattice, and through the Renderer:
// every pixel gets the value it gets traced alone, refined pixels the bits of
// uniform sampling, for fewer eye rays.
#include <doctest/doctest.h>

#include <map>
#include <utility>
#include <vector>

#include "study/image_metrics.h"
#include "tests/accuracy_scenes.h"
#include "tests/test_paths.h"
#include "tracer/adaptive_sampling.h"
#include "tracer/camera.h"
#include "tracer/embree_scene.h"
#include "tracer/sampler.h"
#include "tracer/whitted.h"

namespace rayfarm {

TEST_CASE("accuracy: Rayshade contrast per channel") {
  const Vec3 flat[2] = {{0.5, 0.5, 0.5}, {0.5, 0.5, 0.5}};
  CHECK_FALSE(needs_refinement(flat, 2, 1e-9));
  // Contrast (0.6 - 0.2) / (0.6 + 0.2) = 0.5 in red, 0 in green and blue.
  const Vec3 red_edge[2] = {{0.2, 0.5, 0.5}, {0.6, 0.5, 0.5}};
  CHECK(needs_refinement(red_edge, 2, 0.49));
  CHECK_FALSE(needs_refinement(red_edge, 2, 0.51));
  const Vec3 black[2] = {{0, 0, 0}, {0, 0, 0}};
  CHECK_FALSE(needs_refinement(black, 2, 1e-9));  // no 0/0
  const Vec3 on_black[2] = {{0, 0, 0}, {0, 0, 1e-3}};
  CHECK(needs_refinement(on_black, 2, 0.99));  // contrast 1 in blue
  CHECK(needs_refinement(flat, 2, 0));  // threshold 0 = uniform: always refine
  // The order of the samples does not matter.
  const Vec3 swapped[2] = {red_edge[1], red_edge[0]};
  CHECK(needs_refinement(swapped, 2, 0.49));
  CHECK_FALSE(needs_refinement(swapped, 2, 0.51));
}

TEST_CASE("accuracy: adaptive needs a threshold and more than one sample a pixel") {
  CHECK(is_adaptive(2, 0.1));
  CHECK(is_adaptive(4, 0.1));
  CHECK_FALSE(is_adaptive(1, 0.1));
  CHECK_FALSE(is_adaptive(4, 0));
}

namespace {

// A corner lattice for a width x height image: grey, with chosen points set,
// that fails the test when asked for a point outside the image's lattice.
struct Lattice {
  int width, height;
  std::map<std::pair<int, int>, Vec3> set;
  Vec3 operator()(int i, int j) const {
    REQUIRE(i >= 0);
    REQUIRE(j >= 0);
    REQUIRE(i <= width);
    REQUIRE(j <= height);
    const auto it = set.find({i, j});
    return it == set.end() ? Vec3{0.5, 0.5, 0.5} : it->second;
  }
  bool refines(int x, int y, double threshold) const {
    return neighbourhood_needs_refinement(x, y, width, height, threshold, *this);
  }
};

}  // namespace

TEST_CASE("accuracy: a pixel refines on its own corners, or on its neighbours' nearest ones at 5x the contrast") {
  Lattice lattice{8, 8, {}};
  CHECK_FALSE(lattice.refines(3, 3, 0.1));
  // Contrast 0.2 (0.75 against 0.5) at one of its own corners: above 0.1.
  lattice.set[{4, 4}] = {0.75, 0.5, 0.5};
  CHECK(lattice.refines(3, 3, 0.1));
  CHECK(lattice.refines(4, 4, 0.1));   // the corner is every adjoining pixel's
  CHECK_FALSE(lattice.refines(3, 3, 0.25));
  // The same point two columns to the right: a neighbour's nearest corner,
  // which refines only above 5 times the threshold.
  lattice.set.clear();
  lattice.set[{5, 3}] = {0.75, 0.5, 0.5};
  CHECK_FALSE(lattice.refines(3, 3, 0.1));  // 0.2 < 0.5
  lattice.set[{5, 3}] = {1.5, 0.5, 0.5};    // contrast 0.5 > 0.5 * 0.09
  CHECK(lattice.refines(3, 3, 0.09));
  CHECK_FALSE(lattice.refines(3, 3, 0.11));
  // The nearest corners beyond each edge count, diagonal ones do not.
  for (const auto& [i, j, counts] : std::vector<std::tuple<int, int, bool>>{
           {2, 3, true}, {2, 4, true}, {5, 4, true}, {3, 2, true}, {4, 2, true}, {3, 5, true}, {4, 5, true},
           {2, 2, false}, {5, 5, false}, {6, 3, false}, {3, 6, false}}) {
    CAPTURE(i);
    CAPTURE(j);
    lattice.set.clear();
    lattice.set[{i, j}] = {1.5, 0.5, 0.5};
    CHECK(lattice.refines(3, 3, 0.05) == counts);
  }
}

TEST_CASE("accuracy: pixels on the image's edges look only at corners inside it") {
  Lattice lattice{4, 3, {}};
  for (int y = 0; y < 3; ++y) {
    for (int x = 0; x < 4; ++x) CHECK_FALSE(lattice.refines(x, y, 0.1));  // Lattice fails outside [0,4]x[0,3]
  }
  lattice.set[{4, 3}] = {0.1, 0.1, 0.1};  // the bottom right corner of the image
  CHECK(lattice.refines(3, 2, 0.1));
  CHECK_FALSE(lattice.refines(0, 0, 0.1));
}

TEST_CASE("accuracy: an unrefined pixel is the mean of its four corners") {
  Lattice lattice{2, 2, {}};
  lattice.set[{1, 1}] = {0.1, 0.2, 0.3};
  lattice.set[{2, 1}] = {0.3, 0.2, 0.1};
  lattice.set[{1, 2}] = {1.0, 1.0, 1.0};
  lattice.set[{2, 2}] = {0.0, 0.0, 0.0};
  const Vec3 m = corner_mean(1, 1, lattice);
  CHECK(m.x == doctest::Approx(0.35));
  CHECK(m.y == doctest::Approx(0.35));
  CHECK(m.z == doctest::Approx(0.35));
}

// Through the Renderer: the adaptive path saves eye rays and, where it refines,
// gives the uniform result.
TEST_CASE("accuracy: adaptive rendering saves eye rays and stays close to uniform") {
  const Scene scene = read_nff_file(test::spd_data("balls-2"));
  RenderSettings s = test::small_settings(32, 16);
  RayStats uniform_rays;
  const std::vector<float> uniform = test::render_image(scene, s, &uniform_rays);
  CHECK(uniform_rays.eye == 32u * 32 * 16);

  // A threshold just above 0 refines every pixel whose neighbourhood differs
  // at all: those pixels are bit-identical to uniform sampling, the others
  // see one colour at every corner.
  s.adaptive_contrast = 1e-9;
  RayStats fine_rays;
  const std::vector<float> fine = test::render_image(scene, s, &fine_rays);
  const ImageDiff d_fine = compare_images(uniform, fine, {false, 1e-6});
  INFO("threshold 1e-9: " << fine_rays.eye << " eye rays, " << d_fine.pixels_over << " pixels differ");
  CHECK(fine_rays.eye <= uniform_rays.eye + 33u * 33);
  CHECK(d_fine.pixels_over <= 32 * 32 / 50);

  // The default threshold saves rays at a small cost in error.
  s.adaptive_contrast = 0.1;
  RayStats coarse_rays;
  const std::vector<float> coarse = test::render_image(scene, s, &coarse_rays);
  const ImageDiff d = compare_images(uniform, coarse);
  INFO("threshold 0.1: " << coarse_rays.eye << " eye rays of " << uniform_rays.eye << ", RMSE " << d.rmse);
  CHECK(coarse_rays.eye < uniform_rays.eye * 9 / 10);
  CHECK(d.rmse < 0.03);
}

// The Renderer traces the corner lattice in shared wavefronts, then the
// grids of the pixels it refines together: each pixel must still get the
// value it gets traced alone -- its neighbourhood's corners one ray at a
// time, then its whole grid or its corners' mean -- and a refined pixel the
// bits of the uniform render.
TEST_CASE("accuracy: shared adaptive wavefronts give every pixel the bits it gets alone") {
  const Scene scene = read_nff_file(test::spd_data("balls-2"));
  for (const int spp : {4, 9, 16}) {
    for (const double contrast : {0.05, 0.3}) {
      CAPTURE(spp);
      CAPTURE(contrast);
      RenderSettings s = test::small_settings(24, spp);
      RayStats uniform_rays;
      const std::vector<float> uniform = test::render_image(scene, s, &uniform_rays);
      s.adaptive_contrast = contrast;
      RayStats shared_rays;
      const std::vector<float> shared = test::render_image(scene, s, &shared_rays);
      const EmbreeScene embree(scene, EmbreeOptions{});
      const WhittedIntegrator whitted(scene, embree, s);
      const CameraModel camera(scene.camera, s.width, s.height);
      const int k = grid_size(s.spp);
      RayStats alone_rays;
      const auto corner = [&](int i, int j) {
        const Vec3 dir = camera.direction(i, j);
        Vec3 rgb;
        whitted.trace_eye_rays(&dir, 1, &rgb, alone_rays);
        return rgb;
      };
      int refined = 0, mismatched = 0, unlike_uniform = 0;
      for (int y = 0; y < s.height; ++y) {
        for (int x = 0; x < s.width; ++x) {
          Vec3 alone;
          const size_t at = 3 * (size_t(y) * s.width + x);
          if (neighbourhood_needs_refinement(x, y, s.width, s.height, contrast, corner)) {
            ++refined;
            const PixelGrid grid(pixel_key(s.seed, x, y), k);
            std::vector<Vec3> dirs(k * k), rgb(k * k);
            for (int c = 0; c < k * k; ++c) {
              const PixelSample p = grid.sample(c);
              dirs[c] = camera.direction(x + p.x, y + p.y);
            }
            for (int c = 0; c < k * k; c += 16) {
              whitted.trace_eye_rays(&dirs[c], std::min(16, k * k - c), &rgb[c], alone_rays);
            }
            alone = grid_mean(rgb.data(), k * k);
            unlike_uniform += shared[at] != uniform[at] || shared[at + 1] != uniform[at + 1] ||
                              shared[at + 2] != uniform[at + 2];
          } else {
            alone = corner_mean(x, y, corner);
          }
          mismatched += shared[at] != float(alone.x) || shared[at + 1] != float(alone.y) ||
                        shared[at + 2] != float(alone.z);
        }
      }
      CHECK(mismatched == 0);
      CHECK(unlike_uniform == 0);
      // Every corner once, every refined pixel's grid once.
      CHECK(shared_rays.eye == uint64_t(s.width + 1) * (s.height + 1) + uint64_t(refined) * k * k);
      CHECK(refined > 24 * 24 / 10);  // both kinds of pixel well represented
      CHECK(refined < 24 * 24);
    }
  }
}

}  // namespace rayfarm
