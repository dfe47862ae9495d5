// Image IO tests: EXR keeps floats bit-exactly, 8-bit formats quantise with our
// documented rounding, bad paths fail with the path in the message, PNG works
// without OpenImageIO, and a missing OpenImageIO module is a clear error. Files are inspected through
// image_io.h and their bytes only: this binary does not link OpenImageIO.
#include <doctest/doctest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <regex>
#include <string>
#include <vector>

#include "tests/run_command.h"
#include "tests/test_files.h"
#include "tests/test_paths.h"
#include "tracer/error.h"
#include "tracer/image_io.h"

using namespace rayfarm;
using test::file_bytes;
namespace fs = std::filesystem;

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

// The bit depth in a PNG's IHDR chunk (8-byte signature, length, "IHDR",
// width, height, then the depth byte).
int png_bit_depth(const std::string& bytes) {
  REQUIRE(bytes.size() > 24);
  REQUIRE(bytes.compare(12, 4, "IHDR") == 0);
  return static_cast<unsigned char>(bytes[24]);
}

// A TIFF/EXIF style "YYYY:MM:DD HH:MM:SS" time stamp anywhere in the file.
bool has_time_stamp(const std::string& bytes) {
  static const std::regex stamp("[0-9]{4}:[0-9]{2}:[0-9]{2} [0-9]{2}:[0-9]{2}:[0-9]{2}");
  return std::regex_search(bytes, stamp);
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
  // Exact equality below also proves 32-bit float storage: half floats or
  // 8 bits would round values such as 0.123456789f.
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
    if (ext == "png") CHECK(png_bit_depth(file_bytes(file.path)) == 8);
    const RgbImage back = read_image(file.path);
    REQUIRE(back.rgb.size() == kPixels.size());
    for (size_t i = 0; i < kPixels.size(); ++i) {
      CAPTURE(i);
      // 8-bit storage reads back as exactly k / 255.
      CHECK(back.rgb[i] == doctest::Approx(to_8bit(kPixels[i]) / 255.0f).epsilon(1e-6));
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
    CHECK_FALSE(has_time_stamp(file_bytes(a.path)));
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

TEST_CASE("image_io: an image that cannot be opened or written names the file and the system error, in every format") {
  // PNG said only "cannot open the file" or "Write Error", TIFF 'Could not
  // open "path"', EXR "File output failed": a full disk, a missing folder or
  // too many open files all read alike.
  for (const std::string ext : {".png", ".tif", ".exr"}) {
    CAPTURE(ext);
    const std::string missing = "/nonexistent/dir/out" + ext;
    CHECK_THROWS_WITH_AS(write_image(missing, 4, 2, kPixels),
                         doctest::Contains((missing + ": cannot write ").c_str()), InputError);
    CHECK_THROWS_WITH_AS(write_image(missing, 4, 2, kPixels), doctest::Contains("(No such file or directory)"),
                         InputError);
    const fs::path path = test::scratch_dir("image-write-error") / ("out" + ext);
    std::vector<float> noise(size_t(3) * 96 * 96);
    for (size_t i = 0; i < noise.size(); ++i) noise[i] = static_cast<float>((i * 2654435761u) % 1000) / 1000.0f;
    {
      const test::FileSizeLimit limit(1000);  // as if the disk filled up after 1000 bytes
      CHECK_THROWS_WITH_AS(write_image(path.string(), 96, 96, noise), doctest::Contains("(File too large)"),
                           InputError);
    }
    CHECK_FALSE(fs::exists(path));
  }
  CHECK_THROWS_WITH_AS(write_image("/nonexistent/dir/out.png", 4, 2, kPixels),
                       "/nonexistent/dir/out.png: cannot write PNG: cannot open the file (No such file or directory)",
                       InputError);
}

TEST_CASE("image_io: a path that is only an extension, or a folder, is refused before anything is written") {
  // "-o .png" wrote a hidden file named ".png".
  const fs::path dir = fs::temp_directory_path() / ("rayfarm_image_io_name_" + std::to_string(getpid()));
  fs::create_directories(dir);
  const std::string only_extension = (dir / ".png").string();
  for (const std::string& path : {only_extension, (dir / ".exr").string()}) {
    CAPTURE(path);
    const std::string extension = fs::path(path).filename().string();
    const std::string expected =
        path + ": no file name before the extension " + extension + " (e.g. out" + extension + ")";
    try {
      check_image_path(path);
      FAIL("no error for a name that is only an extension");
    } catch (const InputError& e) {
      CHECK(std::string(e.what()) == expected);
    }
    CHECK_THROWS_WITH_AS(write_image(path, 4, 2, kPixels), expected.c_str(), InputError);
    CHECK_FALSE(fs::exists(path));
  }
  const std::string folder = ": names a folder, not an image file (e.g. " + dir.string() + "/out.png)";
  CHECK_THROWS_WITH_AS(check_image_path(dir.string() + "/"), (dir.string() + "/" + folder).c_str(), InputError);
  CHECK_THROWS_WITH_AS(check_image_path(dir.string()), (dir.string() + folder).c_str(), InputError);
  // A name with a dot in front and an extension is an ordinary file.
  const std::string dotted = (dir / ".hidden.png").string();
  write_image(dotted, 4, 2, kPixels);
  CHECK(fs::exists(dotted));
  fs::remove_all(dir);
}

TEST_CASE("image_io: a missing OpenImageIO module is an error naming the path tried") {
  // The module is loaded on the first non-PNG use; RAYFARM_IMAGEIO overrides
  // where from. A render checks its output path first, so it stops before any
  // rendering.
  const std::string out = "/tmp/rayfarm_image_io_" + std::to_string(getpid()) + "_nomodule.exr";
  const auto r = test::run_command("RAYFARM_IMAGEIO=/nonexistent/librayfarm_imageio.so " + test::rayfarm_exe() +
                                   " render " + test::source_dir() + "/scenes/tetra.nff -o " + out);
  CHECK(r.exit_code != 0);
  CHECK(r.output.find("cannot load the image module") != std::string::npos);
  CHECK(r.output.find("/nonexistent/librayfarm_imageio.so: cannot open shared object file") != std::string::npos);
  // One line: the printer escapes newlines, and the paths tried are joined by "; ".
  CHECK(r.output.find('\n') == r.output.size() - 1);
  CHECK(r.output.find("\\n") == std::string::npos);
  CHECK_FALSE(std::filesystem::exists(out));
}

TEST_CASE("image_io: PNG needs no OpenImageIO module") {
  // libpng writes and reads PNG in-process: a render to .png succeeds with the
  // module unloadable, and reads back with the documented quantisation.
  TempFile out("nomodule.png");
  const auto r = test::run_command("RAYFARM_IMAGEIO=/nonexistent/librayfarm_imageio.so " + test::rayfarm_exe() +
                                   " render " + test::source_dir() + "/scenes/tetra.nff -o " + out.path +
                                   " --width 16 --height 16 --spp 1");
  CHECK(r.exit_code == 0);
  REQUIRE(std::filesystem::exists(out.path));
  const RgbImage back = read_image(out.path);
  CHECK(back.width == 16);
  CHECK(back.height == 16);
}

TEST_CASE("image_io: a file that is not a PNG is an InputError naming the path") {
  TempFile file("not_really.png");
  std::ofstream(file.path) << "P3 1 1 255 0 0 0\n";
  try {
    read_image(file.path);
    FAIL("no error for a bad PNG");
  } catch (const InputError& e) {
    CHECK(std::string(e.what()).rfind(file.path + ": cannot read PNG: ", 0) == 0);
  }
}
