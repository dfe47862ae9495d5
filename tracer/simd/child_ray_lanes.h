// The child-ray kernel (tracer/lane_kernels.h) over a Pack of W doubles
// (pack_*.h): child_rays() (tracer/child_rays.h) for W hits at a time, its
// square root, products and sums in the scalar code's order, its branches
// as selects. Included only by the kernels_*.cpp units.
#pragma once

#include "tracer/lane_kernels.h"

namespace rayfarm::simd {
namespace {

// origin_towards(): p_back where dir . nf < 0, else p_front.
template <class P>
void origin_towards_lanes(const typename P::D dir[3], const typename P::D nf[3], const HitLanes& f, int first,
                          double (*out)[ChildLanes::kLanes]) {
  const auto back = P::lt(dir[0] * nf[0] + dir[1] * nf[1] + dir[2] * nf[2], P::set1(0.0));
  for (int c = 0; c < 3; ++c) {
    P::store(out[c] + first, P::select(back, P::load(f.p_back[c] + first), P::load(f.p_front[c] + first)));
  }
}

template <class P>
void child_ray_lanes(const HitLanes& f, const double (*normals)[HitLanes::kLanes], ChildLanes& out, int count,
                     bool refraction) {
  using D = typename P::D;
  constexpr int kW = P::kWidth;
  const D one = P::set1(1.0);
  uint32_t total_internal = 0;
  for (int first = 0; first < count; first += kW) {
    D d[3], ns[3], nf[3];
    for (int c = 0; c < 3; ++c) {
      d[c] = P::load(f.d[c] + first);
      ns[c] = P::load(normals[c] + first);
      nf[c] = P::load(f.nf[c] + first);
    }
    const D d_dot_n = d[0] * ns[0] + d[1] * ns[1] + d[2] * ns[2];
    D r_dir[3];
    const D twice = P::set1(2.0) * d_dot_n;
    for (int c = 0; c < 3; ++c) {
      r_dir[c] = d[c] - ns[c] * twice;
      P::store(out.mirror_dir[c] + first, r_dir[c]);
    }
    origin_towards_lanes<P>(r_dir, nf, f, first, out.mirror_org);
    if (!refraction) continue;
    const D eta = P::load(out.eta + first);
    const D cos_i = P::neg(d_dot_n);
    const D k = one - eta * eta * (one - cos_i * cos_i);
    total_internal |= P::bits(P::lt(k, P::set1(0.0))) << first;
    const D bend = eta * cos_i - P::sqrt(k);
    D t_dir[3];
    for (int c = 0; c < 3; ++c) {
      t_dir[c] = d[c] * eta + ns[c] * bend;
      P::store(out.refract_dir[c] + first, t_dir[c]);
    }
    origin_towards_lanes<P>(t_dir, nf, f, first, out.refract_org);
  }
  out.total_internal = total_internal & ((1u << count) - 1);  // count <= 16
}

}  // namespace
}  // namespace rayfarm::simd
