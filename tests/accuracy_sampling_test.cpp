// Adaptive supersampling (tracer/adaptive_sampling.h) against uniform k x k
// sampling: bit-identical when refined, cheaper where the coarse samples agree;
// directly and through the Renderer.
#include <doctest/doctest.h>

#include <algorithm>
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
namespace {

// A deterministic "radiance" per cell, different in every cell and channel.
Vec3 noisy_cell(int pixel, int cell) {
  const uint64_t h = sample_hash(7, pixel, 3, cell);
  return {unit_double(h), unit_double(mix64(h)), unit_double(mix64(h + 1))};
}

Vec3 uniform_reference(int k, int pixel) {
  Vec3 sum;
  for (int c = 0; c < k * k; ++c) sum += noisy_cell(pixel, c);
  return sum / (k * k);
}

}  // namespace

TEST_CASE("accuracy: coarse cells are the grid corners") {
  const CoarseCells one = coarse_cells(1);
  CHECK(one.count == 1);
  CHECK(one.index[0] == 0);
  const CoarseCells four = coarse_cells(4);
  REQUIRE(four.count == 4);
  CHECK(four.index[0] == 0);
  CHECK(four.index[1] == 3);
  CHECK(four.index[2] == 12);
  CHECK(four.index[3] == 15);
  CHECK(std::is_sorted(four.index.begin(), four.index.end()));
}

TEST_CASE("accuracy: Rayshade contrast per channel") {
  const Vec3 flat[2] = {{0.5, 0.5, 0.5}, {0.5, 0.5, 0.5}};
  CHECK(max_contrast(flat, 2) == 0);
  const Vec3 red_edge[2] = {{0.2, 0.5, 0.5}, {0.6, 0.5, 0.5}};
  CHECK(max_contrast(red_edge, 2) == doctest::Approx(0.5));  // (0.6-0.2)/(0.6+0.2)
  const Vec3 black[2] = {{0, 0, 0}, {0, 0, 0}};
  CHECK(max_contrast(black, 2) == 0);  // no 0/0
  CHECK(needs_refinement(red_edge, 2, 0.4));
  CHECK_FALSE(needs_refinement(red_edge, 2, 0.6));
  CHECK(needs_refinement(flat, 2, 0));  // threshold 0 = uniform: always refine
}

TEST_CASE("accuracy: adaptive at threshold 0 equals uniform sampling bit for bit") {
  for (int k = 1; k <= 8; ++k) {
    for (int pixel = 0; pixel < 50; ++pixel) {
      int traced = 0;
      const Vec3 v = sample_pixel(k, 0.0, [&](int c) { return noisy_cell(pixel, c); }, &traced);
      CHECK(traced == k * k);
      const Vec3 ref = uniform_reference(k, pixel);
      CHECK(v == ref);
      // A refined pixel (tiny threshold, noisy samples) sums in the same order.
      const Vec3 refined = sample_pixel(k, 1e-9, [&](int c) { return noisy_cell(pixel, c); });
      CHECK(refined == ref);
      // So does grid_mean(), which the renderer takes for a grid it traced
      // whole, with other pixels.
      std::vector<Vec3> cells;
      for (int c = 0; c < k * k; ++c) cells.push_back(noisy_cell(pixel, c));
      CHECK(grid_mean(cells.data(), k * k) == ref);
    }
  }
}

TEST_CASE("accuracy: a flat pixel stops after the four coarse samples") {
  int calls = 0;
  int traced = 0;
  const Vec3 grey{0.25, 0.5, 0.75};
  const Vec3 v = sample_pixel(4, 0.1, [&](int) { ++calls; return grey; }, &traced);
  CHECK(traced == 4);
  CHECK(calls == 4);
  CHECK(v == grey);
  // A 1x1 and a 2x2 grid have nothing to save: always the full grid.
  CHECK(sample_pixel(2, 0.1, [&](int) { return grey; }, &traced) == grey);
  CHECK(traced == 4);
}

TEST_CASE("accuracy: contrast between the corners refines to the full grid") {
  // A vertical edge: left half black, right half white, at 16 spp.
  const auto edge = [](int c) { return (c % 4) < 2 ? Vec3{0, 0, 0} : Vec3{1, 1, 1}; };
  int traced = 0;
  const Vec3 v = sample_pixel(4, 0.25, edge, &traced);
  CHECK(traced == 16);
  CHECK(v.x == doctest::Approx(0.5));
  // A feature strictly between the corners is not seen: the documented price of
  // testing four samples only.
  const auto speck = [](int c) { return c == 5 ? Vec3{1, 1, 1} : Vec3{0.5, 0.5, 0.5}; };
  sample_pixel(4, 0.25, speck, &traced);
  CHECK(traced == 4);
}

TEST_CASE("accuracy: batched adaptive sampling shades every cell once in packets of at most 16") {
  for (int k : {3, 4, 8, 16}) {
    std::vector<int> seen(k * k, 0);
    int batches = 0;
    const auto shade = [&](const int* cells, int count, Vec3* rgb) {
      REQUIRE(count >= 1);
      REQUIRE(count <= kSampleBatch);
      CHECK(std::is_sorted(cells, cells + count));
      for (int i = 0; i < count; ++i) {
        ++seen[cells[i]];
        rgb[i] = noisy_cell(1, cells[i]);
      }
      ++batches;
    };
    const Vec3 v = sample_pixel_batched(k, 1e-9, shade);
    CHECK(v == uniform_reference(k, 1));
    CHECK(std::all_of(seen.begin(), seen.end(), [](int n) { return n == 1; }));
    CHECK(batches >= (k * k + kSampleBatch - 1) / kSampleBatch);
  }
}

}  // namespace rayfarm

namespace rayfarm {

// Through the Renderer: the adaptive path saves eye rays and, where it refines,
// gives the uniform result.
TEST_CASE("accuracy: adaptive rendering saves eye rays and stays close to uniform") {
  const Scene scene = read_nff_file(test::spd_data("balls-2"));
  RenderSettings s = test::small_settings(32, 16);
  RayStats uniform_rays;
  const std::vector<float> uniform = test::render_image(scene, s, &uniform_rays);
  CHECK(uniform_rays.eye == 32u * 32 * 16);

  // A threshold just above 0 refines every pixel whose corners differ at all:
  // those pixels are bit-identical to uniform sampling.
  s.adaptive_contrast = 1e-9;
  RayStats fine_rays;
  const std::vector<float> fine = test::render_image(scene, s, &fine_rays);
  const ImageDiff d_fine = compare_images(uniform, fine, {false, 1e-6});
  INFO("threshold 1e-9: " << fine_rays.eye << " eye rays, " << d_fine.pixels_over << " pixels differ");
  CHECK(fine_rays.eye <= uniform_rays.eye);
  CHECK(d_fine.pixels_over <= 32 * 32 / 50);

  // A Rayshade-like threshold saves rays at a small cost in error.
  s.adaptive_contrast = 0.1;
  RayStats coarse_rays;
  const std::vector<float> coarse = test::render_image(scene, s, &coarse_rays);
  const ImageDiff d = compare_images(uniform, coarse);
  INFO("threshold 0.1: " << coarse_rays.eye << " eye rays of " << uniform_rays.eye << ", RMSE " << d.rmse);
  CHECK(coarse_rays.eye < uniform_rays.eye * 9 / 10);
  CHECK(d.rmse < 0.03);
}

// The Renderer traces neighbouring pixels' corners together, then the
// other cells of the pixels it refines together: each pixel must still get
// the bits it gets traced alone, one batch of at most 16 cells at a time
// (sample_pixel_batched() over the integrator). At 1 and 4 spp the first
// cells are the whole grid, and nothing is left to refine.
TEST_CASE("accuracy: shared adaptive wavefronts give every pixel the bits it gets alone") {
  const Scene scene = read_nff_file(test::spd_data("balls-2"));
  for (const int spp : {1, 4, 9, 16}) {
    for (const double contrast : {0.05, 0.3}) {
      CAPTURE(spp);
      CAPTURE(contrast);
      RenderSettings s = test::small_settings(24, spp);
      s.adaptive_contrast = contrast;
      RayStats shared_rays;
      const std::vector<float> shared = test::render_image(scene, s, &shared_rays);
      const EmbreeScene embree(scene, EmbreeOptions{});
      const WhittedIntegrator whitted(scene, embree, s);
      const CameraModel camera(scene.camera, s.width, s.height);
      const int k = grid_size(s.spp);
      RayStats alone_rays;
      int refined = 0, mismatched = 0;
      for (int y = 0; y < s.height; ++y) {
        for (int x = 0; x < s.width; ++x) {
          const uint64_t key = pixel_key(s.seed, x, y);
          auto shade = [&](const int* cells, int count, Vec3* rgb) {
            Vec3 dirs[kSampleBatch];
            for (int i = 0; i < count; ++i) {
              const PixelSample p = jittered_sample(key, cells[i], k);
              dirs[i] = camera.direction(x + p.x, y + p.y);
            }
            whitted.trace_eye_rays(dirs, count, rgb, alone_rays);
          };
          int traced = 0;
          const Vec3 alone = sample_pixel_batched(k, contrast, shade, &traced);
          refined += traced == k * k;
          const float* got = &shared[3 * (size_t(y) * s.width + x)];
          mismatched += got[0] != float(alone.x) || got[1] != float(alone.y) || got[2] != float(alone.z);
        }
      }
      CHECK(mismatched == 0);
      CHECK(shared_rays.eye == alone_rays.eye);
      if (k >= 3) {  // both kinds of pixel well represented (below, the first cells are the whole grid)
        CHECK(refined > 24 * 24 / 10);
        CHECK(refined < 24 * 24);
      }
    }
  }
}

}  // namespace rayfarm
