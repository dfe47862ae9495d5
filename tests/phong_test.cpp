// phong_terms() (tracer/phong.h), and the Phong kernel that shading runs
// instead: lane by lane the same bits at every width, for random lit hits
// and for the ones where the highlight's power leaves the kernel's common
// path (exponent 0, base 1, tiny and subnormal bases, huge exponents).
#include <doctest/doctest.h>

#include <cmath>
#include <vector>

#include "tests/lane_widths.h"
#include "tracer/phong.h"

namespace rayfarm {
namespace {

struct LitHit {
  Vec3 to_light, ns, d;
  double ks, shine;
};

RandomInputs random(23);
Vec3 unit_vector() {
  const Vec3 v{random.uniform(-1, 1), random.uniform(-1, 1), random.uniform(-1, 1)};
  return v / std::sqrt(dot(v, v));
}

// The light straight above a +z normal, mirrored straight back up: r = +z,
// so r.v = -d.z exactly.
LitHit overhead(double minus_d_z, double ks, double shine) {
  return {{0, 0, 4}, {0, 0, 1}, {0.6, 0, -minus_d_z}, ks, shine};
}

LitHit hit_for(int k) {
  LitHit h{unit_vector() * std::pow(10.0, random.uniform(-2, 3)), unit_vector(), unit_vector(), random.uniform(0, 1),
           std::pow(10.0, random.uniform(-1, 3))};
  switch (k % 13) {
    case 0: h.ks = 0; break;                                 // no highlight
    case 1: h = overhead(1.0, 0.5, 7); break;                // base 1: power 1
    case 2: h = overhead(0.3, 0.5, 0); break;                // exponent 0: power 1
    case 3: h = overhead(1e-3, 0.5, 200); break;             // 2^-1993: below the normal range
    case 4: h = overhead(1e-310, 0.5, 0.5); break;           // subnormal base
    case 5: h = overhead(0.999, 0.5, 1e6); break;            // huge exponent, normal result
    case 6: h = overhead(0.5, 0.5, -2000); break;            // beyond the normal range above
    case 7: h = overhead(-0.5, 0.5, 3); break;               // mirrored light behind the viewer
    default: break;
  }
  return h;
}

TEST_CASE("phong: the kernel gives phong_terms()'s bits, lane by lane, at every width") {
  int highlit = 0, scalar = 0;
  for (int trial = 0; trial < 400; ++trial) {
    const int count = 1 + trial % PhongLanes::kLanes;
    std::vector<LitHit> hits;
    for (int i = 0; i < count; ++i) hits.push_back(hit_for(trial + i));
    for (const char* width : kLaneWidths) {
      CAPTURE(width);
      CAPTURE(trial);
      PhongLanes lanes{};
      for (int i = 0; i < count; ++i) {
        const LitHit& h = hits[i];
        set_phong_lane(lanes, i, h.to_light, h.ns, h.d, h.ks, h.shine);
      }
      lane_kernels(width).phong(lanes, count);
      highlit += __builtin_popcount(lanes.highlit);
      scalar += __builtin_popcount(lanes.scalar);
      for (int i = 0; i < count; ++i) {
        CAPTURE(i);
        const LitHit& h = hits[i];
        const PhongTerms want = phong_terms(h.to_light, h.ns, h.d, h.ks, h.shine);
        const PhongTerms got = phong_lane(lanes, i);
        REQUIRE(same_bits(got.n_dot_l, want.n_dot_l));
        REQUIRE(got.highlit == want.highlit);
        if (want.highlit) REQUIRE(same_bits(got.highlight, want.highlight));
      }
    }
  }
  // Both paths ran: most highlights in lanes, the few near the ends of the
  // normal range scalar.
  CHECK(highlit > 1000);
  CHECK(scalar > 0);
  CHECK(scalar < highlit / 4);
}

TEST_CASE("phong: the terms of a light straight above, viewed from straight above") {
  const PhongTerms t = phong_terms({0, 0, 2}, {0, 0, 1}, {0, 0, -1}, 0.5, 10);
  CHECK(t.n_dot_l == 1);
  CHECK(t.highlit);
  CHECK(t.highlight == 0.5);
  const PhongTerms off = phong_terms({0, 0, 2}, {0, 0, 1}, Vec3{1, 0, -1} / std::sqrt(2.0), 0.5, 10);
  CHECK(off.highlight == doctest::Approx(0.5 * std::pow(std::sqrt(0.5), 10)));
  CHECK_FALSE(phong_terms({0, 0, 2}, {0, 0, 1}, {0, 0, -1}, 0, 10).highlit);
}

TEST_CASE("phong: the facing kernel gives light_in_front()'s bits, lane by lane, at every width") {
  int in_front = 0, behind = 0;
  for (int trial = 0; trial < 400; ++trial) {
    const int count = trial % (HitLanes::kLanes + 1);  // 0 too: a packet of misses
    // Points on a sphere of radius 2 around the light's foot, normals
    // random: about half face it; every fifth trial puts the light in the
    // tangent plane of some points, where d is 0 and counts as behind.
    const Vec3 light = random.point(10);
    alignas(64) double p[3][HitLanes::kLanes], ns[3][HitLanes::kLanes];
    for (int i = 0; i < HitLanes::kLanes; ++i) {
      Vec3 pi = light + unit_vector() * 2.0, ni = unit_vector();
      if (trial % 5 == 0 && i % 2 == 0) pi = light, ni = {0, 0, 1};  // light at the point: d == 0
      for (int c = 0; c < 3; ++c) p[c][i] = pi[c], ns[c][i] = ni[c];
    }
    uint32_t want = 0;
    for (int i = 0; i < count; ++i) {
      want |= uint32_t(light_in_front(lane_vec(p, i), lane_vec(ns, i), light)) << i;
    }
    in_front += __builtin_popcount(want);
    behind += count - __builtin_popcount(want);
    for (const char* width : kLaneWidths) {
      CAPTURE(width);
      CAPTURE(trial);
      REQUIRE(lane_kernels(width).facing(p, ns, &light.x, count) == want);
    }
  }
  CHECK(in_front > 500);
  CHECK(behind > 500);
}

}  // namespace
}  // namespace rayfarm
