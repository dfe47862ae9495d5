// An image file written while its rows are rendered. Converting and
// compressing a 512x512 PNG took 5.8 ms (tetra) to 15.7 ms (rings) of a
// process, all of it after the last pixel when the image is written whole;
// here a thread of its own converts and compresses each band of rows as the
// render finishes it, so when the render ends only the last band is left.
// Other formats are written whole at finish() (OpenImageIO takes whole
// images). Either way the file has write_image()'s bytes and appears under
// its name whole, at finish(), or not at all (output_file.h).
#pragma once

#include <memory>
#include <string>
#include <vector>

namespace rayfarm {

class StreamedImageFile {
 public:
  // `rgb` is the image, filled in top row first: width * height * 3 floats
  // from the first rows_done() on, when it must stop being resized; it must
  // stay alive until finish() or destruction. Throws InputError naming
  // `path` if the file cannot be created.
  StreamedImageFile(const std::string& path, int width, int height, const std::vector<float>& rgb);
  // Unfinished (the render failed): stops writing and removes the temporary;
  // `path` is untouched.
  ~StreamedImageFile();
  StreamedImageFile(const StreamedImageFile&) = delete;
  StreamedImageFile& operator=(const StreamedImageFile&) = delete;

  // Rows [0, rows) of `rgb` are final and will not change. Rethrows the
  // writer's error, if it has failed, so that a long render stops early.
  void rows_done(int rows);
  // All rows are final: waits for the writer, then puts the file in place.
  // Throws InputError naming `path`.
  void finish();

 private:
  struct Writer;
  std::unique_ptr<Writer> writer_;
};

}  // namespace rayfarm
