// The lane kernels for AVX2. This file alone is compiled for that ISA
// (CMakeLists.txt), so it includes no inline code of the tracer's.
#include "tracer/simd/child_ray_lanes.h"
#include "tracer/simd/cone_lanes.h"
#include "tracer/simd/facing_lanes.h"
#include "tracer/simd/fill_lanes.h"
#include "tracer/simd/hit_frame_lanes.h"
#include "tracer/simd/interior_lanes.h"
#include "tracer/simd/kernels.h"
#include "tracer/simd/pack_avx2.h"
#include "tracer/simd/phong_lanes.h"
#include "tracer/simd/sphere_lanes.h"
#include "tracer/simd/triangle_lanes.h"

namespace rayfarm::simd {

LaneKernels kernels_avx2() {
  return {fill_lanes<Pack>,      triangle_lanes<Pack>, sphere_lanes<Pack>, cone_lanes<Pack>, interior_lanes<Pack>, sphere_lanes_per_lane<Pack>, cone_lanes_per_lane<Pack>,
          hit_frame_lanes<Pack>, phong_lanes<Pack>,    facing_lanes<Pack>, child_ray_lanes<Pack>};
}

}  // namespace rayfarm::simd
