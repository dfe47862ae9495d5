// Image memory; see image_memory.h.
#include "tracer/image_memory.h"

#include <unistd.h>

#include <cstdio>

#include "tracer/error.h"

namespace rayfarm {

uint64_t float_image_bytes(int width, int rows) { return uint64_t(width) * uint64_t(rows) * 3 * sizeof(float); }

uint64_t physical_memory_bytes() {
  const long pages = ::sysconf(_SC_PHYS_PAGES), page = ::sysconf(_SC_PAGESIZE);
  // Unknown: no limit of ours; the allocation itself is the last word.
  return pages > 0 && page > 0 ? uint64_t(pages) * uint64_t(page) : UINT64_MAX;
}

void check_image_memory(int width, int rows, uint64_t limit_bytes, const std::string& holder) {
  const uint64_t need = float_image_bytes(width, rows);
  if (need <= limit_bytes) return;
  const auto size = [](uint64_t bytes) {
    char text[32];
    const double gib = double(bytes) / double(1ull << 30);
    if (gib >= 0.1)
      std::snprintf(text, sizeof text, "%.1f GiB", gib);
    else
      std::snprintf(text, sizeof text, "%.1f MiB", double(bytes) / double(1ull << 20));
    return std::string(text);
  };
  throw InputError("a " + std::to_string(width) + "x" + std::to_string(rows) + " image needs " + size(need) +
                   " as float RGB; " + holder + " is " + size(limit_bytes));
}

}  // namespace rayfarm
