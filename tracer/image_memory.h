// Image memory: what an image's float RGB pixels take (12 bytes a pixel), and
// the check that the process about to hold them can. Without it a frame too
// large for the machine ends in std::bad_alloc or the kernel's OOM killer after
// the work has begun -- and a head-node service, which resumes unfinished jobs
// when it restarts, would die on the same job after every restart.
#pragma once

#include <cstdint>
#include <string>

namespace rayfarm {

uint64_t float_image_bytes(int width, int rows);

// This machine's physical memory (sysconf), the default limit.
uint64_t physical_memory_bytes();

// Throws InputError "a 65536x65536 image needs 48.0 GiB as float RGB; <holder>
// is 23.5 GiB" when width x rows pixels exceed limit_bytes.
void check_image_memory(int width, int rows, uint64_t limit_bytes, const std::string& holder);

}  // namespace rayfarm
