// PNG files through libpng, without OpenImageIO: PNG is the everyday output,
// and loading OpenImageIO's dependency tree costs a process ~0.25 s of symbol
// binding and ~120 MB of resident memory. Writes 8-bit RGB with zlib level 1 and
// no row filters (the images are small; speed matters more than a few percent
// of size); reads any PNG libpng can convert to 8-bit RGB.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace rayfarm {

// Whether `path` ends in ".png" (any case): the files this codec owns.
bool is_png_path(const std::string& path);

// A PNG file written a band of rows at a time, top row first: the same bytes
// as write_png() of the whole image. Throws InputError naming the path when
// the file cannot be opened or written.
class PngRowWriter {
 public:
  PngRowWriter(const std::string& path, int width, int height);
  ~PngRowWriter();  // closes the file, finished or not
  PngRowWriter(const PngRowWriter&) = delete;
  PngRowWriter& operator=(const PngRowWriter&) = delete;

  // The next `rows` rows, width * 3 bytes each.
  void write_rows(const uint8_t* rgb, int rows);
  // After the last row: the stream's end, then the file closed.
  void finish();

 private:
  struct Stream;
  std::unique_ptr<Stream> stream_;
};

// Writes width * height * 3 bytes, row-major, top row first, in place (see
// output_file.h for writing a file atomically). Throws InputError naming the
// path when the file cannot be written.
void write_png(const std::string& path, int width, int height, const uint8_t* rgb);

// The PNG stream of width * height * 3 bytes, in memory (for serving over HTTP,
// e.g. the status page's preview). Throws InputError naming `what`.
std::string encode_png(int width, int height, const uint8_t* rgb, const std::string& what);

// Reads a PNG as 8-bit RGB (grey is replicated, alpha dropped, 16-bit reduced).
// Throws InputError naming the path.
std::vector<uint8_t> read_png(const std::string& path, int& width, int& height);

}  // namespace rayfarm
