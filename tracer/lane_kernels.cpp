// Filling a packet's lanes, and picking the widest lane kernels (tracer/simd/)
// the CPU runs.
#include "tracer/lane_kernels.h"

#include "tracer/shapes.h"
#include "tracer/simd/kernels.h"

namespace rayfarm {

void set_ray_lane(RayLanes& lanes, int i, const ShearedRay& ray, double tfar) {
  for (int axis = 0; axis < 3; ++axis) {
    lanes.org[axis][i] = ray.org[axis];
    lanes.dir[axis][i] = ray.dir[axis];
  }
  lanes.sx[i] = ray.sx;
  lanes.sy[i] = ray.sy;
  lanes.sz[i] = ray.sz;
  lanes.tfar[i] = tfar;
  if (i == 0) {
    lanes.kx = ray.kx;
    lanes.ky = ray.ky;
    lanes.kz = ray.kz;
    lanes.shared_axes = true;
  } else {
    lanes.shared_axes &= ray.kx == lanes.kx && ray.ky == lanes.ky && ray.kz == lanes.kz;
  }
}

LaneKernels lane_kernels(const std::string& max_isa) {
  const bool cap_sse = max_isa == "sse2" || max_isa == "sse4.2" || max_isa == "avx";
  const bool cap_avx2 = cap_sse || max_isa == "avx2";
  if (!cap_avx2 && __builtin_cpu_supports("avx512f")) return simd::kernels_avx512();
  if (!cap_sse && __builtin_cpu_supports("avx2")) return simd::kernels_avx2();
  return simd::kernels_sse2();
}

}  // namespace rayfarm
