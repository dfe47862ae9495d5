// The heap on 2 MB pages (tracer/heap_pages.h). Each ctest entry runs in a
// process of its own, so changing this process's allocator settings here
// touches no other test. Where the sanitizers bring their own allocator the
// call does nothing, and there is nothing to check.
#include <doctest/doctest.h>
#include <unistd.h>

#include <cctype>
#include <cstdint>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "tracer/heap_pages.h"

using namespace rayfarm;

namespace {

#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
constexpr bool kSanitized = true;
#else
constexpr bool kSanitized = false;
#endif

std::string read_all(const char* path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// The VmFlags of the mapping holding `address`, from /proc/self/smaps ("" if
// none holds it): "hg" among them is the MADV_HUGEPAGE advice.
std::string vm_flags_at(uintptr_t address) {
  std::istringstream smaps(read_all("/proc/self/smaps"));
  std::string line;
  bool holds = false;
  while (std::getline(smaps, line)) {
    if (!line.empty() && std::isxdigit(static_cast<unsigned char>(line[0])) && line.find('-') != std::string::npos) {
      const uintptr_t start = std::stoull(line, nullptr, 16);
      const uintptr_t end = std::stoull(line.substr(line.find('-') + 1), nullptr, 16);
      holds = start <= address && address < end;
    } else if (holds && line.rfind("VmFlags:", 0) == 0) {
      return line.substr(8) + " ";
    }
  }
  return "";
}

// kB of transparent huge pages in the [heap] mappings (madvise splits the
// heap into several), from /proc/self/smaps.
long heap_huge_kb() {
  std::istringstream smaps(read_all("/proc/self/smaps"));
  std::string line;
  bool in_heap = false;
  long kb = 0;
  while (std::getline(smaps, line)) {
    if (!line.empty() && std::isxdigit(static_cast<unsigned char>(line[0])) && line.find('-') != std::string::npos) {
      in_heap = line.find("[heap]") != std::string::npos;
    } else if (in_heap && line.rfind("AnonHugePages:", 0) == 0) {
      kb += std::stol(line.substr(14));
    }
  }
  return kb;
}

}  // namespace

TEST_CASE("heap pages: a render-sized block comes from the heap, on 2 MB pages where the kernel has them") {
  if (kSanitized) return;
  use_huge_heap_pages();
  std::vector<float> image(512 * 512 * 3, 0.5f);  // a 512x512 float image, 3 MB
  const auto at = reinterpret_cast<uintptr_t>(image.data());
  const auto heap_end = reinterpret_cast<uintptr_t>(sbrk(0));
  // Below the break: the heap, not an mmap of its own (those lie far above it).
  CHECK(at < heap_end);
  CHECK(heap_end - at < (uintptr_t(1) << 30));
  const std::string thp = read_all("/sys/kernel/mm/transparent_hugepage/enabled");
  if (thp.find("[madvise]") != std::string::npos || thp.find("[always]") != std::string::npos) {
    // The advice is ours to give; whether the kernel finds free 2 MB pages
    // at fault time depends on its memory's fragmentation, so their count is
    // reported, not checked.
    // The image's end: its start may lie in the few pages before the first
    // 2 MB boundary, which are left unadvised.
    const uintptr_t last = at + image.size() * sizeof(float) - 1;
    CHECK(vm_flags_at(last).find(" hg ") != std::string::npos);
    MESSAGE("heap on 2 MB pages: " << heap_huge_kb() << " kB");
  }
}
