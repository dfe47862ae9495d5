// Images written while they render (tracer/streamed_image_file.h): the bytes
// write_image() writes, whatever the bands; nothing under the final name until
// finish(); nothing left behind by a render that fails; a write error reported
// while the render still runs.
#include <doctest/doctest.h>
#include <sys/resource.h>

#include <chrono>
#include <csignal>
#include <filesystem>
#include <thread>
#include <vector>

#include "tests/test_files.h"
#include "tracer/error.h"
#include "tracer/image_io.h"
#include "tracer/streamed_image_file.h"

using namespace rayfarm;
namespace fs = std::filesystem;

namespace {

using test::file_bytes;
using test::files_in;
using test::FileSizeLimit;

// Values that no compressor shrinks much, all 256 levels and out-of-range ones.
std::vector<float> noise_image(int width, int height) {
  std::vector<float> rgb(size_t(3) * width * height);
  uint32_t state = 12345;
  for (float& v : rgb) {
    state = state * 1664525u + 1013904223u;
    v = static_cast<float>(state >> 8) / float(1 << 24) * 1.2f - 0.1f;
  }
  return rgb;
}

}  // namespace

TEST_CASE("streamed_image_file: a PNG streamed in uneven bands has write_image's bytes") {
  const fs::path dir = test::scratch_dir("streamed-bytes");
  const int width = 37;
  const int height = 23;
  const std::vector<float> whole = noise_image(width, height);
  write_image((dir / "whole.png").string(), width, height, whole);

  std::vector<float> rgb(whole.size(), 0.0f);
  const fs::path streamed = dir / "streamed.png";
  StreamedImageFile image(streamed.string(), width, height, rgb);
  const size_t row = size_t(3) * width;
  int done = 0;
  for (const int band : {1, 5, 0, 9, 8}) {  // the rows of each band appear just before they are handed over
    std::copy(whole.begin() + row * done, whole.begin() + row * (done + band), rgb.begin() + row * done);
    done += band;
    image.rows_done(done);
    CHECK_FALSE(fs::exists(streamed));  // nothing under the final name before finish()
  }
  image.finish();
  CHECK(file_bytes(streamed) == file_bytes(dir / "whole.png"));
  CHECK(files_in(dir) == 2);  // no temporary left
}

TEST_CASE("streamed_image_file: other formats are written whole at finish, with write_image's bytes") {
  const fs::path dir = test::scratch_dir("streamed-exr");
  const std::vector<float> rgb = noise_image(6, 4);
  write_image((dir / "whole.exr").string(), 6, 4, rgb);
  StreamedImageFile image((dir / "streamed.exr").string(), 6, 4, rgb);
  image.rows_done(2);
  CHECK(files_in(dir) == 1);
  image.finish();
  CHECK(file_bytes(dir / "streamed.exr") == file_bytes(dir / "whole.exr"));
}

TEST_CASE("streamed_image_file: a render that fails leaves the old file and no temporary") {
  const fs::path dir = test::scratch_dir("streamed-abandoned");
  const fs::path path = dir / "out.png";
  test::write_file(path, "the last good image");
  const std::vector<float> rgb = noise_image(16, 16);
  {
    StreamedImageFile image(path.string(), 16, 16, rgb);
    image.rows_done(7);
    CHECK(files_in(dir) == 2);  // the old file and the temporary being written
  }  // destroyed unfinished, as when the render throws
  CHECK(file_bytes(path) == "the last good image");
  CHECK(files_in(dir) == 1);
}

TEST_CASE("streamed_image_file: a folder that cannot be written is an InputError naming the file") {
  const std::vector<float> rgb(3 * 4 * 4, 0.5f);
  CHECK_THROWS_WITH_AS(StreamedImageFile("/proc/out.png", 4, 4, rgb), doctest::Contains("/proc/out.png"),
                       InputError);
  StreamedImageFile wrong_size((test::scratch_dir("streamed-size") / "out.png").string(), 4, 5, rgb);
  CHECK_THROWS_AS(wrong_size.rows_done(1), std::invalid_argument);
  StreamedImageFile right_size((test::scratch_dir("streamed-size") / "out.png").string(), 4, 4, rgb);
  CHECK_THROWS_AS(right_size.rows_done(5), std::invalid_argument);
}

TEST_CASE("streamed_image_file: a write error stops the render early and names the file") {
  const fs::path dir = test::scratch_dir("streamed-full");
  const fs::path path = dir / "out.png";
  const int side = 96;  // 27 KB of noise: more than libpng buffers before its first write
  const std::vector<float> rgb = noise_image(side, side);
  const FileSizeLimit limit(1000);  // as if the disk filled up after 1000 bytes
  StreamedImageFile image(path.string(), side, side, rgb);
  bool stopped = false;
  for (int wait = 0; wait < 1000 && !stopped; ++wait) {  // the encoder fails on its own thread
    try {
      image.rows_done(side - 1);
    } catch (const InputError& e) {
      stopped = true;
      CHECK(std::string(e.what()).find(path.string() + ": cannot write PNG") == 0);
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  CHECK(stopped);
  CHECK_FALSE(fs::exists(path));
}
