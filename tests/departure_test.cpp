// DepartingLanes (tracer/departure.h): which lanes skip a primitive, all 16
// at once and lane by lane, for runs of any primIDs.
#include <doctest/doctest.h>

#include <cstdint>
#include <initializer_list>

#include "tracer/departure.h"

using namespace rayfarm;

namespace {
constexpr uint32_t kTriangles = 0, kSpheres = 1, kCones = 2;  // EmbreeScene's kinds
}

TEST_CASE("departure: lanes skip their own run of primitives, of their own kind only") {
  // Even lanes depart a cone's four slices [10i, 10i + 4), odd lanes sphere
  // i, lane 15 nothing; lane 14's run straddles 2^31, where a signed compare
  // of the offsets would go wrong.
  Departure d[DepartingLanes::kLanes];
  for (uint32_t i = 0; i < 15; ++i) d[i] = i % 2 ? Departure{kSpheres, i, 1} : Departure{kCones, 10 * i, 4};
  d[14] = {kCones, 0x7FFFFFFEu, 4};
  DepartingLanes lanes;
  lanes.set(d, DepartingLanes::kLanes);
  CHECK(lanes.skipping(kCones, 40) == 1u << 4);
  CHECK(lanes.skipping(kCones, 43) == 1u << 4);
  CHECK(lanes.skipping(kCones, 44) == 0);
  CHECK(lanes.skipping(kCones, 39) == 0);
  CHECK(lanes.skipping(kSpheres, 5) == 1u << 5);
  CHECK(lanes.skipping(kSpheres, 40) == 0);  // a cone's run, not a sphere's
  CHECK(lanes.skipping(kCones, 5) == 0);     // a sphere's index, not a cone's
  CHECK(lanes.skipping(kCones, 0x80000001u) == 1u << 14);
  CHECK(lanes.skipping(kCones, 0x7FFFFFFDu) == 0);
  CHECK(lanes.skipping(kCones, 0x80000002u) == 0);
  CHECK(lanes.skipping(kTriangles, 40) == 0);
  // Lane by lane, the same bits.
  int agreed = 0;
  for (uint32_t kind : {kTriangles, kSpheres, kCones}) {
    for (uint32_t prim : {0u, 1u, 3u, 5u, 20u, 23u, 24u, 130u, 0x7FFFFFFEu, 0x80000001u, 0x80000002u, 0xFFFFFFFFu}) {
      uint32_t one_by_one = 0;
      for (unsigned i = 0; i < DepartingLanes::kLanes; ++i) one_by_one |= uint32_t(lanes.skips(i, kind, prim)) << i;
      CHECK(one_by_one == lanes.skipping(kind, prim));
      agreed += one_by_one != 0;
    }
  }
  CHECK(agreed >= 8);
  // Fewer rays than lanes: the lanes past them depart nothing.
  lanes.set(d, 4);
  CHECK(lanes.skipping(kSpheres, 3) == 1u << 3);
  CHECK(lanes.skipping(kSpheres, 5) == 0);
  lanes.set(nullptr, 16);
  CHECK(lanes.skipping(kSpheres, 3) == 0);
  CHECK_FALSE(lanes.skips(3, kSpheres, 3));
  // A single ray is lane 0.
  lanes.set_single({kCones, 7, 2});
  CHECK(lanes.skips(0, kCones, 8));
  CHECK_FALSE(lanes.skips(0, kCones, 9));
  CHECK_FALSE(lanes.skips(0, kSpheres, 7));
  lanes.set_single({});
  CHECK_FALSE(lanes.skips(0, kCones, 8));
}
