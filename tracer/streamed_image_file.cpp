// Images written while they render; see streamed_image_file.h.
#include "tracer/streamed_image_file.h"

#include <condition_variable>
#include <exception>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <thread>

#include "tracer/error.h"
#include "tracer/image_io.h"
#include "tracer/output_file.h"
#include "tracer/png_file.h"

namespace rayfarm {

struct StreamedImageFile::Writer {
  Writer(const std::string& path, int width, int height, const std::vector<float>& rgb)
      : path(path), width(width), height(height), rgb(rgb) {
    if (width <= 0 || height <= 0) throw std::invalid_argument("StreamedImageFile: an empty image");
    if (!is_png_path(path)) return;
    file.emplace(path);
    try {
      out.emplace(file->temp_path(), width, height);
    } catch (const InputError& e) {
      throw file->naming_path(e);
    }
    encoder = std::thread([this] { encode(); });
  }

  ~Writer() {
    if (!encoder.joinable()) return;
    {
      const std::lock_guard<std::mutex> lock(mutex);
      abandoned = true;
    }
    wake.notify_one();
    encoder.join();
  }

  // The encoder thread: each band of final rows to bytes, then to the PNG
  // stream, until the last row; an error is kept for the render's thread.
  void encode() {
    try {
      const size_t row_floats = size_t(3) * width;
      std::vector<uint8_t> bytes;
      for (int written = 0; written < height;) {
        int ready = 0;
        {
          std::unique_lock<std::mutex> lock(mutex);
          wake.wait(lock, [&] { return rows_ready > written || abandoned; });
          if (abandoned) return;
          ready = rows_ready;
        }
        const size_t count = row_floats * (ready - written);
        bytes.resize(count);
        to_8bit(rgb.data() + row_floats * written, count, bytes.data());
        out->write_rows(bytes.data(), ready - written);
        written = ready;
      }
      out->finish();
    } catch (...) {
      const std::lock_guard<std::mutex> lock(mutex);
      error = std::current_exception();
    }
  }

  void check_size() const {
    if (rgb.size() != static_cast<size_t>(width) * height * 3)
      throw std::invalid_argument("StreamedImageFile: rgb does not hold width * height * 3 values");
  }

  void rethrow_error() {
    if (!error) return;
    try {
      std::rethrow_exception(error);
    } catch (const InputError& e) {
      throw file->naming_path(e);
    }
  }

  bool streams() const { return out.has_value(); }

  const std::string path;
  const int width;
  const int height;
  const std::vector<float>& rgb;
  std::optional<AtomicOutputFile> file;  // a PNG's: the temporary the encoder writes
  std::optional<PngRowWriter> out;       // used by the encoder alone
  std::mutex mutex;
  std::condition_variable wake;
  int rows_ready = 0;  // guarded by mutex, as are the two below
  bool abandoned = false;
  std::exception_ptr error;
  std::thread encoder;  // last: started once everything above exists
};

StreamedImageFile::StreamedImageFile(const std::string& path, int width, int height, const std::vector<float>& rgb)
    : writer_(std::make_unique<Writer>(path, width, height, rgb)) {}

StreamedImageFile::~StreamedImageFile() = default;

void StreamedImageFile::rows_done(int rows) {
  Writer& w = *writer_;
  w.check_size();
  if (rows < 0 || rows > w.height) throw std::invalid_argument("StreamedImageFile: rows_done beyond the image");
  if (!w.streams()) return;
  {
    const std::lock_guard<std::mutex> lock(w.mutex);
    w.rethrow_error();
    w.rows_ready = rows;
  }
  w.wake.notify_one();
}

void StreamedImageFile::finish() {
  Writer& w = *writer_;
  w.check_size();
  if (!w.streams()) return write_image(w.path, w.width, w.height, w.rgb);
  rows_done(w.height);
  w.encoder.join();
  w.rethrow_error();
  w.file->commit();
}

}  // namespace rayfarm
