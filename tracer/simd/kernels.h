// The lane kernels (tracer/lane_kernels.h) once per ISA, each set in a
// translation unit of its own compiled for that ISA (CMakeLists.txt): use a
// set only on a CPU that runs it.
#pragma once

#include "tracer/lane_kernels.h"

namespace rayfarm::simd {

LaneKernels kernels_sse2();
LaneKernels kernels_avx2();
LaneKernels kernels_avx512();

}  // namespace rayfarm::simd
