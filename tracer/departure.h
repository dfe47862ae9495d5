// Departure: the sphere or cone (all its slices) a ray leaves from the
// outside, away from it: a mirror ray off an outside hit, a shadow ray
// towards a light in front of one. A line leaving a convex solid's outside
// cannot meet it again, so that primitive's exact test is skipped for the
// ray, in every walk alike (EmbreeScene's callbacks, lane kernels and shadow
// caches): it could only report the rounding of the ray's start (a
// self-intersection). Triangles have none (a polygon may be part of a
// concave mesh). A departure is named by its run of Embree primitives, so
// that asking whether a primitive is the departed one reads no memory.
#pragma once

#include <emmintrin.h>

#include <climits>
#include <cstdint>
#include <cstring>

namespace rayfarm {

struct Departure {
  static constexpr uint32_t kNone = UINT32_MAX;  // Embree's invalid geometry id
  uint32_t geom = kNone;          // the kind (EmbreeScene::kSpheres or kCones), or kNone
  uint32_t first = 0, count = 0;  // primIDs: the sphere, or the cone's slices
};

// Whether primID x lies in the run of `count` from `first` (one unsigned
// compare: below `first`, x - first wraps to a large number).
inline bool in_run(uint32_t x, uint32_t first, uint32_t count) { return x - first < count; }

// Whether a ray that departs `d` skips primitive `prim` (a primID) of kind `geom`.
inline bool departs(const Departure& d, uint32_t geom, uint32_t prim) {
  return d.geom == geom && in_run(prim, d.first, d.count);
}

// The departures of the rays of one Embree call: a packet's 16 lanes, or a
// single ray's lane 0. The callbacks ask for every primitive the rays meet,
// so a packet's lanes are compared all at once (a first version, lane by
// lane, rendered rings 1.02x slower than without departures).
class DepartingLanes {
 public:
  static constexpr int kLanes = 16;
  static constexpr uint32_t kKinds = 3;  // geometry ids below this (EmbreeScene::kKinds)

  // Lanes [0, count) from departures[0, count); none when `departures` is null.
  void set(const Departure* departures, int count) {
    std::memset(lanes_of_, 0, sizeof lanes_of_);
    if (!departures) return;
    // skipping() reads every lane and masks out those that depart nothing.
    std::memset(first_, 0, sizeof first_);
    std::memset(count_, 0, sizeof count_);
    for (int i = 0; i < count; ++i) {
      if (departures[i].geom != Departure::kNone) set_lane(i, departures[i]);
    }
  }
  // A single ray's departure, as lane 0.
  void set_single(const Departure& d) {
    std::memset(lanes_of_, 0, sizeof lanes_of_);
    if (d.geom != Departure::kNone) set_lane(0, d);
  }
  // Whether lane `lane` skips primitive `prim` of kind `geom`.
  bool skips(unsigned lane, uint32_t geom, uint32_t prim) const {
    return ((departing(geom) >> lane) & 1) && in_run(prim, uint32_t(first_[lane]), uint32_t(count_[lane]));
  }
  // The lanes (as bits) that skip primitive `prim` of kind `geom`.
  uint32_t skipping(uint32_t geom, uint32_t prim) const {
    const uint32_t of_kind = departing(geom);
    return of_kind ? within(prim) & of_kind : 0;
  }

 private:
  void set_lane(int i, const Departure& d) {
    if (d.geom >= kKinds) return;
    first_[i] = static_cast<int>(d.first);
    count_[i] = static_cast<int>(d.count);
    lanes_of_[d.geom] |= 1u << i;
  }
  uint32_t departing(uint32_t geom) const { return geom < kKinds ? lanes_of_[geom] : 0; }
  // Bit i set where in_run(x, first_[i], count_[i]), for the 16 lanes: SSE2
  // compares signed, so both sides of the unsigned compare are shifted by 2^31.
  uint32_t within(uint32_t x) const {
    const __m128i bias = _mm_set1_epi32(INT_MIN), xs = _mm_set1_epi32(static_cast<int>(x));
    __m128i in[4];
    for (int q = 0; q < 4; ++q) {
      const __m128i f = _mm_loadu_si128(reinterpret_cast<const __m128i*>(first_ + 4 * q));
      const __m128i c = _mm_loadu_si128(reinterpret_cast<const __m128i*>(count_ + 4 * q));
      in[q] = _mm_cmplt_epi32(_mm_xor_si128(_mm_sub_epi32(xs, f), bias), _mm_xor_si128(c, bias));
    }
    const __m128i bytes = _mm_packs_epi16(_mm_packs_epi32(in[0], in[1]), _mm_packs_epi32(in[2], in[3]));
    return static_cast<uint32_t>(_mm_movemask_epi8(bytes));
  }

  uint32_t lanes_of_[kKinds] = {};  // per kind, the lanes that depart one of that kind
  // Each departing lane's run; set only where a lane departs, unless set()
  // cleared them for within().
  int first_[kLanes], count_[kLanes];
};

}  // namespace rayfarm
