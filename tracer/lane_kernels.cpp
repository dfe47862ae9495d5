// Picks the widest lane kernels (tracer/simd/) the CPU runs.
#include "tracer/lane_kernels.h"

#include <iterator>

#include "tracer/embree_scene.h"
#include "tracer/simd/kernels.h"

namespace rayfarm {

LaneKernels lane_kernels(const std::string& max_isa) {
  // Positions in kEmbreeIsas, narrowest first; no cap (or a name the scene
  // rejects anyway) allows all.
  auto rank = [](const std::string& isa) {
    int i = 0;
    while (i < int(std::size(kEmbreeIsas)) && isa != kEmbreeIsas[i]) ++i;
    return i;
  };
  const int cap = rank(max_isa);
  if (cap >= rank("avx512") && __builtin_cpu_supports("avx512f")) return simd::kernels_avx512();
  if (cap >= rank("avx2") && __builtin_cpu_supports("avx2")) return simd::kernels_avx2();
  return simd::kernels_sse2();
}

}  // namespace rayfarm
