// Progressive preview (status/preview.h): nearest-done-row fill, the PNG it
// serves, and what the coarse-to-fine row order buys it on a real render.
#include <doctest/doctest.h>

#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "broker/row_order.h"
#include "status/preview.h"
#include "tests/test_paths.h"
#include "tracer/image_io.h"
#include "tracer/nff_reader.h"
#include "tracer/png_file.h"
#include "tracer/renderer.h"

using namespace rayfarm;

namespace {

std::vector<bool> done_rows(int height, const std::vector<int>& rows) {
  std::vector<bool> done(static_cast<size_t>(height), false);
  for (int y : rows) done[static_cast<size_t>(y)] = true;
  return done;
}

// Mean absolute difference of two 8-bit images, in 8-bit steps.
double mean_abs_difference(const std::vector<uint8_t>& a, const std::vector<uint8_t>& b) {
  double sum = 0;
  for (size_t i = 0; i < a.size(); ++i) sum += std::abs(int(a[i]) - int(b[i]));
  return sum / static_cast<double>(a.size());
}

}  // namespace

TEST_CASE("preview: rows not done show the nearest done row, the upper on a tie") {
  CHECK(preview_source_rows(done_rows(6, {1, 4})) == std::vector<int>{1, 1, 1, 4, 4, 4});
  CHECK(preview_source_rows(done_rows(5, {0, 2})) == std::vector<int>{0, 0, 2, 2, 2});
  CHECK(preview_source_rows(done_rows(3, {})) == std::vector<int>{-1, -1, -1});
  CHECK(preview_fill_distance(done_rows(6, {1, 4})) == 1);
  CHECK(preview_fill_distance(done_rows(8, {0})) == 7);
  CHECK(preview_fill_distance(done_rows(3, {})) == 3);
  CHECK(preview_fill_distance(done_rows(3, {0, 1, 2})) == 0);
}

TEST_CASE("preview: filled rows copy their source row, nothing done is black") {
  const int w = 2, h = 4;
  std::vector<float> rgb(static_cast<size_t>(w * h * 3), 0.f);
  for (int x = 0; x < w * 3; ++x) rgb[static_cast<size_t>(2 * w * 3 + x)] = 0.5f;  // row 2 only
  const std::vector<uint8_t> out = preview_rgb8(w, h, rgb, done_rows(h, {2}));
  for (uint8_t v : out) CHECK(v == to_8bit(0.5f));
  for (uint8_t v : preview_rgb8(w, h, rgb, done_rows(h, {}))) CHECK(v == 0);
}

TEST_CASE("preview: the PNG decodes to the preview, and a complete preview is the final PNG's pixels") {
  const int w = 5, h = 3;
  std::vector<float> rgb(static_cast<size_t>(w * h * 3));
  for (size_t i = 0; i < rgb.size(); ++i) rgb[i] = static_cast<float>(i) / static_cast<float>(rgb.size());
  const std::vector<bool> all = done_rows(h, {0, 1, 2});
  const std::string png = preview_png(w, h, rgb, all);
  REQUIRE(png.size() > 8);
  CHECK(png.compare(0, 8, "\x89PNG\r\n\x1a\n") == 0);

  const std::string preview_path = "preview_test_preview.png", final_path = "preview_test_final.png";
  std::FILE* f = std::fopen(preview_path.c_str(), "wb");
  REQUIRE(f);
  std::fwrite(png.data(), 1, png.size(), f);
  std::fclose(f);
  write_image(final_path, w, h, rgb);
  int pw = 0, ph = 0, fw = 0, fh = 0;
  const std::vector<uint8_t> decoded = read_png(preview_path, pw, ph);
  const std::vector<uint8_t> final_pixels = read_png(final_path, fw, fh);
  CHECK(pw == w);
  CHECK(ph == h);
  CHECK(decoded == preview_rgb8(w, h, rgb, all));
  CHECK(decoded == final_pixels);
  std::remove(preview_path.c_str());
  std::remove(final_path.c_str());
}

TEST_CASE("preview: at 10% of the rows, coarse to fine covers the frame and is closer to the final image") {
  RenderSettings settings;
  settings.width = settings.height = 128;
  settings.spp = 1;
  settings.threads = 1;
  const Scene scene = read_nff_file(test::source_dir() + "/scenes/balls.nff");
  const Renderer renderer(scene, settings);
  std::vector<float> rgb;
  renderer.render_rows(0, settings.height, rgb);
  const std::vector<uint8_t> final_image = preview_rgb8(128, 128, rgb, std::vector<bool>(128, true));

  const std::vector<int> order = coarse_to_fine(128);
  const std::vector<int> interleaved(order.begin(), order.begin() + 13);  // 10%
  std::vector<int> top_down;
  for (int y = 0; y < 13; ++y) top_down.push_back(y);

  CHECK(preview_fill_distance(done_rows(128, interleaved)) < 16);
  CHECK(preview_fill_distance(done_rows(128, top_down)) == 128 - 13);
  const double error_interleaved = mean_abs_difference(preview_rgb8(128, 128, rgb, done_rows(128, interleaved)), final_image);
  const double error_top_down = mean_abs_difference(preview_rgb8(128, 128, rgb, done_rows(128, top_down)), final_image);
  MESSAGE("mean |preview - final| at 10%: coarse to fine " << error_interleaved << ", top down " << error_top_down);
  CHECK(error_interleaved < 0.7 * error_top_down);
}
