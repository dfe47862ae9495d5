// Image IO tests: EXR keeps floats bit-exactly, 8-bit formats quantise with our
// documented rounding, and bad paths fail with the path in the message.
#include <doctest/doctest.h>

#include <OpenImageIO/imageio.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "tracer/error.h"
#include "tracer/image_io.h"

using namespace rayfarm;

namespace {

// A per-process scratch file, so parallel test runs do not collide.
struct TempFile {
  std::string path;
  explicit TempFile(const std::string& name)
      : path((std::filesystem::temp_directory_path() /
              ("rayfarm_image_io_" + std::to_string(getpid()) + "_" + name))
                 .string()) {}
  ~TempFile() { std::filesystem::remove(path); }
};

std::string file_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

OIIO::TypeDesc stored_type(const std::string& path) {
  auto in = OIIO::ImageInput::open(path);
  REQUIRE(in);
  return in->spec().format;
}

// 4 x 2 pixels spanning the interesting cases of the 8-bit conversion.
const std::vector<float> kPixels{0.0f, 0.5f,  1.0f,  1.5f,    -0.2f, NAN,   0.5f / 255, 0.49f / 255,
                                 0.998f, 0.25f, 0.75f, 1e-8f, 3.25f, 0.1f, 0.123456789f, 0.9f,
                                 0.2f,   0.3f,  0.4f,  0.6f,  0.7f,  0.8f, 0.05f,        1.0f};

}  // namespace

TEST_CASE("image_io: 8-bit conversion clamps and rounds to nearest") {
  CHECK(to_8bit(0.0f) == 0);
  CHECK(to_8bit(-3.0f) == 0);
  CHECK(to_8bit(NAN) == 0);
  CHECK(to_8bit(1.0f) == 255);
  CHECK(to_8bit(7.0f) == 255);
  CHECK(to_8bit(INFINITY) == 255);
  CHECK(to_8bit(0.5f) == 128);  // 127.5 rounds up
  CHECK(to_8bit(0.51f / 255) == 1);
  CHECK(to_8bit(0.49f / 255) == 0);
  for (int i = 0; i <= 255; ++i) CHECK(to_8bit(i / 255.0f) == i);
}

TEST_CASE("image_io: EXR round-trips floats exactly") {
  TempFile file("roundtrip.exr");
  std::vector<float> rgb = kPixels;
  rgb[5] = 0.0f;  // NaN never equals itself; keep the comparison simple
  write_image(file.path, 4, 2, rgb);
  CHECK(stored_type(file.path) == OIIO::TypeDesc::FLOAT);
  const RgbImage back = read_image(file.path);
  CHECK(back.width == 4);
  CHECK(back.height == 2);
  CHECK(back.rgb == rgb);
}

TEST_CASE("image_io: png and tif store the 8-bit quantisation") {
  // The per-index comparison also checks the layout (row-major, top row first),
  // since neighbouring values differ.
  for (const std::string ext : {"png", "tif"}) {
    CAPTURE(ext);
    TempFile file("quant." + ext);
    write_image(file.path, 4, 2, kPixels);
    CHECK(stored_type(file.path) == OIIO::TypeDesc::UINT8);
    const RgbImage back = read_image(file.path);
    REQUIRE(back.rgb.size() == kPixels.size());
    for (size_t i = 0; i < kPixels.size(); ++i) {
      CAPTURE(i);
      CHECK(std::lround(back.rgb[i] * 255) == to_8bit(kPixels[i]));
    }
  }
}

TEST_CASE("image_io: writing the same pixels twice gives the same bytes") {
  for (const std::string ext : {"png", "tif", "exr"}) {
    CAPTURE(ext);
    TempFile a("same_a." + ext), b("same_b." + ext);
    write_image(a.path, 4, 2, kPixels);
    write_image(b.path, 4, 2, kPixels);
    CHECK(file_bytes(a.path) == file_bytes(b.path));
    // No time stamp, so files written in different seconds agree too.
    auto in = OIIO::ImageInput::open(a.path);
    REQUIRE(in);
    CHECK(in->spec().get_string_attribute("DateTime") == "");
  }
}

TEST_CASE("image_io: bad extension, unwritable path and missing file are InputErrors") {
  const std::string bad = "/tmp/rayfarm_image_io_" + std::to_string(getpid()) + ".xyz";
  try {
    write_image(bad, 4, 2, kPixels);
    FAIL("no error for an unknown extension");
  } catch (const InputError& e) {
    CHECK(std::string(e.what()).rfind(bad + ": unknown image format (use .png, .tif, .exr, ...)", 0) == 0);
  }
  CHECK_FALSE(std::filesystem::exists(bad));
  CHECK_THROWS_AS(write_image("/nonexistent/dir/out.png", 4, 2, kPixels), InputError);
  try {
    write_image("/nonexistent/dir/out.exr", 4, 2, kPixels);
    FAIL("no error for an unwritable path");
  } catch (const InputError& e) {
    CHECK(std::string(e.what()).rfind("/nonexistent/dir/out.exr: cannot write image", 0) == 0);
  }
  CHECK_THROWS_AS(read_image("/nonexistent/in.png"), InputError);
  CHECK_THROWS_AS(write_image("/tmp/x.png", 4, 2, std::vector<float>(5)), std::invalid_argument);
}
