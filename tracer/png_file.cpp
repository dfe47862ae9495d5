// png_file.h over libpng: the classic API for writing (the simplified one
// cannot set the compression level), the simplified API for reading.
#include "tracer/png_file.h"

#include <png.h>

#include <cctype>
#include <csetjmp>
#include <cstdio>

#include "tracer/error.h"

namespace rayfarm {
namespace {

// libpng reports errors by longjmp. The jump stays inside encode(), whose
// frame holds only trivially destructible state, and the message is copied
// out so the caller can throw an ordinary exception.
struct PngError {
  char message[256] = "";
};
void record_png_error(png_structp png, png_const_charp message) {
  auto* error = static_cast<PngError*>(png_get_error_ptr(png));
  std::snprintf(error->message, sizeof error->message, "%s", message);
  png_longjmp(png, 1);
}
void ignore_png_warning(png_structp, png_const_charp) {}

// Writes the PNG stream to `file`; false (with error->message) on failure.
bool encode(std::FILE* file, int width, int height, const uint8_t* rgb, PngError* error) {
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, error, record_png_error, ignore_png_warning);
  if (!png) return false;
  png_infop info = png_create_info_struct(png);
  if (!info || setjmp(png_jmpbuf(png))) {
    png_destroy_write_struct(&png, &info);
    return false;
  }
  png_init_io(png, file);
  // Fastest zlib level, no row filters: see png_file.h.
  png_set_compression_level(png, 1);
  png_set_filter(png, PNG_FILTER_TYPE_BASE, PNG_FILTER_NONE);
  png_set_IHDR(png, info, static_cast<png_uint_32>(width), static_cast<png_uint_32>(height), 8, PNG_COLOR_TYPE_RGB,
               PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_BASE, PNG_FILTER_TYPE_BASE);
  png_write_info(png, info);
  const size_t stride = static_cast<size_t>(width) * 3;
  for (int y = 0; y < height; ++y) png_write_row(png, rgb + stride * y);
  png_write_end(png, nullptr);
  png_destroy_write_struct(&png, &info);
  return true;
}

}  // namespace

bool is_png_path(const std::string& path) {
  if (path.size() < 4) return false;
  std::string ext = path.substr(path.size() - 4);
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return ext == ".png";
}

void write_png(const std::string& path, int width, int height, const uint8_t* rgb) {
  std::FILE* file = std::fopen(path.c_str(), "wb");
  if (!file) throw InputError(path + ": cannot write PNG: cannot open the file");
  PngError error;
  const bool encoded = encode(file, width, height, rgb, &error);
  const bool closed = std::fclose(file) == 0;
  if (!encoded) throw InputError(path + ": cannot write PNG: " + error.message);
  if (!closed) throw InputError(path + ": cannot write PNG: write failed");
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
