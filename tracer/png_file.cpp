// png_file.h over libpng: the classic API for writing (the simplified one
// cannot set the compression level), the simplified API for reading.
#include "tracer/png_file.h"

#include <png.h>

#include <cctype>
#include <cerrno>
#include <csetjmp>
#include <cstdio>
#include <cstring>
#include <utility>

#include "tracer/error.h"

namespace rayfarm {
namespace {

// libpng reports errors by longjmp, back into guarded() below, whose frame
// and libpng's own hold only trivially destructible state; the message is
// copied out so the caller can throw an ordinary exception.
struct PngError {
  char message[256] = "";
};
void record_png_error(png_structp png, png_const_charp message) {
  auto* error = static_cast<PngError*>(png_get_error_ptr(png));
  std::snprintf(error->message, sizeof error->message, "%s", message);
  png_longjmp(png, 1);
}
void ignore_png_warning(png_structp, png_const_charp) {}

// "what (system error)": libpng's own writer says only "Write Error", which
// hides whether the disk is full, the file too large or the handle bad.
std::string with_errno(const char* what, int error) { return std::string(what) + " (" + std::strerror(error) + ")"; }

// The message is formatted on the stack: png_error leaves by longjmp, past
// any destructor, so a std::string here would never be freed.
[[noreturn]] void fail_io(png_structp png, const char* what) {
  char message[256];
  std::snprintf(message, sizeof message, "%s (%s)", what, std::strerror(errno));
  png_error(png, message);  // copied by record_png_error before the longjmp
}

void write_to_file(png_structp png, png_bytep data, size_t length) {
  if (std::fwrite(data, 1, length, static_cast<std::FILE*>(png_get_io_ptr(png))) != length)
    fail_io(png, "write failed");
}
void flush_file(png_structp png) {
  if (std::fflush(static_cast<std::FILE*>(png_get_io_ptr(png))) != 0) fail_io(png, "write failed");
}

}  // namespace

bool is_png_path(const std::string& path) {
  if (path.size() < 4) return false;
  std::string ext = path.substr(path.size() - 4);
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return ext == ".png";
}

struct PngRowWriter::Stream {
  std::string path;
  std::FILE* file = nullptr;
  png_structp png = nullptr;
  png_infop info = nullptr;
  PngError error;
  size_t stride = 0;

  ~Stream() {
    if (png) png_destroy_write_struct(&png, &info);
    if (file) std::fclose(file);
  }

  [[noreturn]] void fail(const std::string& what) const { throw InputError(path + ": cannot write PNG: " + what); }

  // Runs libpng calls; a libpng error ends them and throws InputError.
  template <typename Calls>
  void guarded(Calls calls) {
    if (setjmp(png_jmpbuf(png))) fail(error.message);
    calls();
  }
};

PngRowWriter::PngRowWriter(const std::string& path, int width, int height) : stream_(std::make_unique<Stream>()) {
  Stream& s = *stream_;
  s.path = path;
  s.stride = static_cast<size_t>(width) * 3;
  s.file = std::fopen(path.c_str(), "wb");
  if (!s.file) s.fail(with_errno("cannot open the file", errno));
  s.png = png_create_write_struct(PNG_LIBPNG_VER_STRING, &s.error, record_png_error, ignore_png_warning);
  if (s.png) s.info = png_create_info_struct(s.png);
  if (!s.info) s.fail("out of memory");
  s.guarded([&] {
    png_set_write_fn(s.png, s.file, write_to_file, flush_file);
    // Fastest zlib level, no row filters: see png_file.h.
    png_set_compression_level(s.png, 1);
    png_set_filter(s.png, PNG_FILTER_TYPE_BASE, PNG_FILTER_NONE);
    png_set_IHDR(s.png, s.info, static_cast<png_uint_32>(width), static_cast<png_uint_32>(height), 8,
                 PNG_COLOR_TYPE_RGB, PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_BASE, PNG_FILTER_TYPE_BASE);
    png_write_info(s.png, s.info);
  });
}

PngRowWriter::~PngRowWriter() = default;

void PngRowWriter::write_rows(const uint8_t* rgb, int rows) {
  Stream& s = *stream_;
  s.guarded([&] {
    for (int y = 0; y < rows; ++y) png_write_row(s.png, rgb + s.stride * y);
  });
}

void PngRowWriter::finish() {
  Stream& s = *stream_;
  s.guarded([&] { png_write_end(s.png, nullptr); });
  png_destroy_write_struct(&s.png, &s.info);
  const bool closed = std::fclose(std::exchange(s.file, nullptr)) == 0;
  if (!closed) s.fail(with_errno("write failed", errno));
}

void write_png(const std::string& path, int width, int height, const uint8_t* rgb) {
  PngRowWriter out(path, width, height);
  out.write_rows(rgb, height);
  out.finish();
}

// The simplified API: the memory writer takes no compression level, and a
// preview is served once and dropped, so libpng's default is fine.
std::string encode_png(int width, int height, const uint8_t* rgb, const std::string& what) {
  png_image image{};
  image.version = PNG_IMAGE_VERSION;
  image.width = static_cast<png_uint_32>(width);
  image.height = static_cast<png_uint_32>(height);
  image.format = PNG_FORMAT_RGB;
  png_alloc_size_t size = 0;
  auto write = [&](void* buffer) {
    if (png_image_write_to_memory(&image, buffer, &size, 0, rgb, 0, nullptr)) return;
    const std::string message = what + ": cannot encode PNG: " + image.message;
    png_image_free(&image);
    throw InputError(message);
  };
  write(nullptr);  // sizes the stream
  std::string png(size, '\0');
  write(png.data());
  png.resize(size);
  return png;
}

std::vector<uint8_t> read_png(const std::string& path, int& width, int& height) {
  png_image image{};
  image.version = PNG_IMAGE_VERSION;
  auto fail = [&](const char* what) {
    const std::string message = path + ": cannot read PNG: " + (what ? what : image.message);
    png_image_free(&image);
    throw InputError(message);
  };
  if (!png_image_begin_read_from_file(&image, path.c_str())) fail(nullptr);
  image.format = PNG_FORMAT_RGB;
  std::vector<uint8_t> rgb(PNG_IMAGE_SIZE(image));
  if (!png_image_finish_read(&image, nullptr, rgb.data(), 0, nullptr)) fail(nullptr);
  width = static_cast<int>(image.width);
  height = static_cast<int>(image.height);
  return rgb;
}

}  // namespace rayfarm
