// The process heap on 2 MB pages. The first touch of every 4 KB page is a
// page fault, and on the virtual machines rayfarm is measured on one costs
// 13-18 us (about 1 us on bare metal): a 512x512 render touches some 2,000
// pages (its float image alone 768), and setting up gears' 36,610 triangles
// touched 8,700. Linux backs memory with transparent 2 MB pages only where
// a program asks for them (the usual "madvise" setting), so rayfarm asks for
// its heap. Pixels do not depend on it: it changes where memory comes from,
// never what is computed.
#pragma once

namespace rayfarm {

// Call once, first thing in main(): from then on blocks up to 32 MB come from
// the heap (not one mmap each, faulted in anew every time), freed memory stays
// in the process, and the next 64 MB of heap are backed by 2 MB pages where
// the kernel has them. A no-op where that cannot be done (other C libraries,
// sanitizer builds, whose allocator is their own).
void use_huge_heap_pages();

}  // namespace rayfarm
