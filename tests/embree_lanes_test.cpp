// The lane masks of the packets rayfarm hands Embree (tracer/embree_lanes.h):
// which lanes of the packet a callback's window of Embree's rays is, which
// lanes Embree skips, and which it marked occluded.
#include <doctest/doctest.h>

#include <cmath>
#include <cstdint>
#include <numeric>

#include "tracer/embree_lanes.h"

using namespace rayfarm;

namespace {

constexpr int kLanes = 16;

// n rays with ids first, first+1, ... and the valid flags of `valid_bits`.
struct Rays {
  alignas(16) int valid[kLanes] = {};
  alignas(16) int ids[kLanes] = {};
  Rays(unsigned n, int first, uint32_t valid_bits) {
    std::iota(ids, ids + n, first);
    for (unsigned i = 0; i < n; ++i) valid[i] = (valid_bits >> i) & 1 ? -1 : 0;
  }
};

}  // namespace

TEST_CASE("embree lanes: a whole packet and Embree's windows of 8 and 4 are the packet's own lanes") {
  const Rays whole(16, 0, 0xbeefu);
  LaneWindow w = lane_window(whole.valid, whole.ids, 16, kLanes);
  CHECK(w.active == 0xbeefu);
  CHECK(w.first == 0);

  const Rays upper_half(8, 8, 0x81u);  // AVX2's second window: lanes 8 and 15 valid
  w = lane_window(upper_half.valid, upper_half.ids, 8, kLanes);
  CHECK(w.active == 0x8100u);
  CHECK(w.first == 8);

  const Rays third_quarter(4, 8, 0x6u);  // SSE's third window: lanes 9 and 10 valid
  w = lane_window(third_quarter.valid, third_quarter.ids, 4, kLanes);
  CHECK(w.active == 0x600u);
  CHECK(w.first == 8);
}

TEST_CASE("embree lanes: rays that are not a window of the packet give none") {
  SUBCASE("a single ray") {
    const Rays one(1, 3, 1);
    CHECK(lane_window(one.valid, one.ids, 1, kLanes).active == 0);
  }
  SUBCASE("a width Embree does not use") {
    const Rays two(2, 0, 3);
    CHECK(lane_window(two.valid, two.ids, 2, kLanes).active == 0);
  }
  SUBCASE("reordered rays") {
    Rays swapped(8, 0, 0xffu);
    std::swap(swapped.ids[2], swapped.ids[5]);
    CHECK(lane_window(swapped.valid, swapped.ids, 8, kLanes).active == 0);
  }
  SUBCASE("a window not aligned to its width") {
    const Rays shifted(8, 4, 0xffu);
    CHECK(lane_window(shifted.valid, shifted.ids, 8, kLanes).active == 0);
  }
  SUBCASE("ids past the packet") {
    const Rays beyond(8, 16, 0xffu);
    CHECK(lane_window(beyond.valid, beyond.ids, 8, kLanes).active == 0);
  }
  SUBCASE("negative ids") {
    const Rays negative(4, -4, 0xfu);
    CHECK(lane_window(negative.valid, negative.ids, 4, kLanes).active == 0);
  }
}

TEST_CASE("embree lanes: an invalid ray's id does not matter") {
  // Lanes Embree marks invalid are never tested, whatever id they carry.
  Rays rays(8, 8, 0xf0u);
  rays.ids[1] = 1234;
  const LaneWindow w = lane_window(rays.valid, rays.ids, 8, kLanes);
  CHECK(w.active == 0xf000u);
  CHECK(w.first == 8);
}

TEST_CASE("embree lanes: a disabled lane is invalid both ways, and occluded lanes are those Embree made negative") {
  alignas(64) RTCRay16 rays{};
  alignas(64) int valid[kLanes];
  for (int i = 0; i < kLanes; ++i) {
    valid[i] = -1;
    rays.tnear[i] = 0.0f;
    rays.tfar[i] = 1.0f;
  }
  disable_lane(rays, valid, 5);
  CHECK(valid[5] == 0);
  CHECK(rays.tnear[5] > rays.tfar[5]);  // Embree's ray-stream code skips such a lane
  CHECK(valid[4] == -1);
  CHECK(rays.tnear[4] <= rays.tfar[4]);

  rays.tfar[0] = -INFINITY;
  rays.tfar[13] = -INFINITY;
  rays.tfar[7] = 0.0f;  // a ray that ends at its start is not occluded
  CHECK(negative_lanes(rays.tfar) == ((1u << 0) | (1u << 13)));
}
