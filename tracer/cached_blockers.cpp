// EmbreeScene's shadow caches (embree_scene.h): whether the blockers a
// cache holds block a ray, by the exact test the callbacks run and skipped
// as they skip it; for a ray alone, and for a batch of rays walked one by
// one, each with its own cache, tested at once in the lane kernels, one
// primitive a lane. (The caches of packets walked together are tested in
// embree_scene.cpp, beside the packets' queries.)
#include <utility>

#include "tracer/embree_scene.h"
#include "tracer/ray_lane_fill.h"

namespace rayfarm {

ConeLaneShape EmbreeScene::cone_lane_shape(const ConeSlice& s) {
  const ConeShape& c = s.shape;
  return {{c.center.x, c.center.y, c.center.z}, {c.axis.x, c.axis.y, c.axis.z}, c.half_length, c.mid_radius,
          c.slope, c.bound2, c.rmax2, s.s_lo, s.s_hi};
}

// Whether `o` blocks org + t*dir, t in (0, tfar): the ray as Embree holds it
// through the same test the callbacks run, skipped as they skip it.
bool EmbreeScene::blocks(const Occluder& o, const ShearedRay& exact, double tfar, const Departure& departure) const {
  if (o.geom == RTC_INVALID_GEOMETRY_ID || departs(departure, o.geom, o.prim)) return false;
  TraceHit hit;
  return hit_primitive(o.geom, o.prim, exact, tfar, hit);
}

// Whether the cache's first or second blocker blocks the ray; the second
// becomes the first when it does.
bool EmbreeScene::cached_blocks(ShadowCache& cache, const ShearedRay& exact, double tfar,
                                const Departure& departure) const {
  if (blocks(cache.first, exact, tfar, departure)) return true;
  if (!blocks(cache.second, exact, tfar, departure)) return false;
  std::swap(cache.first, cache.second);
  return true;
}

// Which of the rays of `soa` (0..count-1) the occluders occluders[i] block,
// of the `lanes` given, each ray testing its own: spheres and cone slices in
// the lane kernels, one primitive a lane, triangle pieces one by one.
// Departed occluders and none (geom invalid) block nothing.
uint32_t EmbreeScene::blocks_apart(const Occluder* occluders, uint32_t lanes, const RayLanes& soa,
                                   const Departure* departures) const {
  alignas(64) SphereLaneShapes spheres;
  alignas(64) ConeLaneShapes cones;
  uint32_t sphere_lanes = 0, cone_lanes = 0, blocked = 0;
  for (uint32_t bits = lanes; bits; bits &= bits - 1) {
    const int i = __builtin_ctz(bits);
    const Occluder& o = occluders[i];
    if (o.geom == RTC_INVALID_GEOMETRY_ID || (departures && departs(departures[i], o.geom, o.prim))) continue;
    if (o.geom == kSpheres) {
      const LocalSphere& s = spheres_[o.prim];
      const double center[3] = {s.center.x, s.center.y, s.center.z};
      set_sphere_lane(spheres, i, center, s.radius);
      sphere_lanes |= 1u << i;
    } else if (o.geom == kCones) {
      set_cone_lane(cones, i, cone_lane_shape(cone_slices_[o.prim]));
      cone_lanes |= 1u << i;
    } else {
      TraceHit hit;
      blocked |= uint32_t(hit_primitive(o.geom, o.prim, lane_ray(soa, i), soa.tfar[i], hit)) << i;
    }
  }
  if (sphere_lanes) {
    alignas(64) double t[RayLanes::kLanes];
    blocked |= lane_kernels_.sphere_per_lane(soa, sphere_lanes, spheres, t);
  }
  if (cone_lanes) {
    ConeLaneHits hits;
    blocked |= lane_kernels_.cone_per_lane(soa, cone_lanes, cones, hits);
  }
  return blocked;
}

// The rays of `soa` (0..count-1) that their caches (caches[i]; null: none)
// block, first entries and then second ones, as cached_blocks() answers each
// ray: a second entry that blocks becomes its cache's first, once, however
// many of the rays share the cache.
uint32_t EmbreeScene::cached_blocks_apart(ShadowCache* const* caches, const RayLanes& soa, int count,
                                          const Departure* departures) const {
  Occluder first[kPacket], second[kPacket];
  uint32_t with_cache = 0;
  for (int i = 0; i < count; ++i) {
    if (!caches[i]) continue;
    first[i] = caches[i]->first;
    second[i] = caches[i]->second;
    with_cache |= 1u << i;
  }
  const uint32_t by_first = blocks_apart(first, with_cache, soa, departures);
  const uint32_t by_second = blocks_apart(second, with_cache & ~by_first, soa, departures);
  for (uint32_t bits = by_second; bits; bits &= bits - 1) {
    ShadowCache& cache = *caches[__builtin_ctz(bits)];
    if (cache.second == second[__builtin_ctz(bits)]) std::swap(cache.first, cache.second);
  }
  return by_first | by_second;
}

}  // namespace rayfarm
