// The heap on 2 MB pages (see the header).
#include "tracer/heap_pages.h"

#include <cstdint>
#include <cstdlib>  // first: defines __GLIBC__ where the C library is glibc

#if defined(__linux__) && defined(__GLIBC__)
#include <malloc.h>
#include <sys/mman.h>
#include <unistd.h>
#endif

namespace rayfarm {

namespace {

#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
constexpr bool kOwnAllocator = true;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer)
constexpr bool kOwnAllocator = true;
#else
constexpr bool kOwnAllocator = false;
#endif
#else
constexpr bool kOwnAllocator = false;
#endif

}  // namespace

void use_huge_heap_pages() {
#if defined(__linux__) && defined(__GLIBC__)
  if (kOwnAllocator) return;
  constexpr uintptr_t kHugePage = uintptr_t(2) << 20;
  constexpr size_t kReserve = size_t(64) << 20;
  // glibc serves blocks from 128 KB up with an mmap of their own, unmapped on
  // free, so a vector that doubles faults in all its pages again each time.
  // 32 MB is the largest threshold glibc takes.
  mallopt(M_MMAP_THRESHOLD, 32 << 20);
  mallopt(M_TRIM_THRESHOLD, static_cast<int>(kReserve));  // a service gives back what it frees beyond that
  mallopt(M_TOP_PAD, 0);
  // New blocks are cut from the start of the heap's free top. Line that start
  // up with a 2 MB boundary: take what is free at the top now, then the gap
  // from the break to the boundary (kept for good: a few pages, never touched).
  static void* held[2] = {};  // static: still reachable, not leaked
  if (const size_t top = mallinfo2().keepcost; top > 4096) held[0] = std::malloc(top - 4096);
  const auto start = reinterpret_cast<uintptr_t>(sbrk(0));
  const uintptr_t boundary = (start + kHugePage - 1) & ~(kHugePage - 1);
  if (boundary - start > 4096) held[1] = std::malloc(boundary - start - 64);
  // Grow the heap once by the reserve, untouched but for glibc's chunk
  // headers, and ask for 2 MB pages over it (whole 2 MB pages only).
  mallopt(M_TOP_PAD, static_cast<int>(kReserve));
  void* volatile block = std::malloc(kReserve / 4);  // volatile: the pair must not be optimised away
  std::free(block);
  const auto end = reinterpret_cast<uintptr_t>(sbrk(0)) & ~(kHugePage - 1);
  if (end > boundary) madvise(reinterpret_cast<void*>(boundary), end - boundary, MADV_HUGEPAGE);
  (void)held;
#endif
}

}  // namespace rayfarm
