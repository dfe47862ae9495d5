// Picks the widest lane kernels (tracer/simd/) the CPU runs.
#include "tracer/lane_kernels.h"

#include "tracer/simd/kernels.h"

namespace rayfarm {

LaneKernels lane_kernels(const std::string& max_isa) {
  const bool cap_sse = max_isa == "sse2" || max_isa == "sse4.2" || max_isa == "avx";
  const bool cap_avx2 = cap_sse || max_isa == "avx2";
  if (!cap_avx2 && __builtin_cpu_supports("avx512f")) return simd::kernels_avx512();
  if (!cap_sse && __builtin_cpu_supports("avx2")) return simd::kernels_avx2();
  return simd::kernels_sse2();
}

}  // namespace rayfarm
