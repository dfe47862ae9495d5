// hit_frame() (tracer/hit_frame.h), and the hit-frame kernel that shading
// runs instead: lane by lane the same bits at every width, for random hits
// and for the awkward ones (normals with no usable length, points near the
// origin where the offset is a float step, grazing and tangent rays).
#include <doctest/doctest.h>

#include <cmath>
#include <vector>

#include "tests/lane_widths.h"
#include "tracer/hit_frame.h"

namespace rayfarm {
namespace {

struct Hit {
  Vec3 org, dir;
  double t;
  Vec3 ng;
};

RandomInputs random(11);

// Hit k of a trial: mostly random at scales from 1e-3 to 1e4, every so often
// one of the cases where hit_frame() branches.
Hit hit_for(int k) {
  const double scale = std::pow(10.0, random.uniform(-3, 4));
  Hit h{random.point(scale), random.point(1), random.uniform(0, 3), random.point(1)};
  switch (k % 11) {
    case 0: h.ng = {0, 0, 0}; break;                        // no normal: faces the ray
    case 1: h.ng = {1e200, -1e200, 0}; break;               // |ng|^2 overflows: faces the ray too
    case 2: h.dir = {0, 0, 0}; break;                       // no direction: +z
    case 3: h.org = {0, 0, 0}, h.t = random.uniform(0, 1e-3); break;  // near the origin: float offsets
    case 4: h.ng = cross(h.dir, random.point(1)); break;   // grazing: n . d = 0 up to rounding
    case 5: h.org = {-h.org.x, 0, h.org.z}, h.dir.y = 0; break;  // a zero coordinate
    case 6: h.t = 0; break;
    default: break;
  }
  return h;
}

TEST_CASE("hit frame: the kernel gives hit_frame()'s bits, lane by lane, at every width") {
  for (int trial = 0; trial < 300; ++trial) {
    const int count = 1 + trial % HitLanes::kLanes;
    std::vector<Hit> hits;
    for (int i = 0; i < count; ++i) hits.push_back(hit_for(trial + i));
    for (const char* width : kLaneWidths) {
      CAPTURE(width);
      CAPTURE(trial);
      HitLanes lanes{};
      for (int i = 0; i < count; ++i) set_hit_lane(lanes, i, hits[i].org, hits[i].dir, hits[i].t, hits[i].ng);
      lane_kernels(width).hit_frames(lanes, count);
      for (int i = 0; i < count; ++i) {
        CAPTURE(i);
        const HitFrame want = hit_frame(hits[i].org, hits[i].dir, hits[i].t, hits[i].ng);
        const HitFrame got = hit_lane(lanes, i);
        REQUIRE(same_bits(got.p, want.p));
        REQUIRE(same_bits(got.d, want.d));
        REQUIRE(same_bits(got.nf, want.nf));
        REQUIRE(same_bits(got.p_front, want.p_front));
        REQUIRE(same_bits(got.p_back, want.p_back));
        REQUIRE(got.entering == want.entering);
      }
    }
  }
}

TEST_CASE("hit frame: the normal faces the ray, and the offset origins lie on either side") {
  const Vec3 org{0, 0, 5}, dir{0, 0, -2};
  SUBCASE("arriving against the normal: entering, nf as given (unit)") {
    const HitFrame f = hit_frame(org, dir, 2.0, Vec3{0, 0, 3});
    CHECK(f.entering);
    CHECK(f.nf == Vec3{0, 0, 1});
    CHECK(f.d == Vec3{0, 0, -1});
    CHECK(f.p == Vec3{0, 0, 1});
    CHECK(f.p_front.z > 1);
    CHECK(f.p_back.z < 1);
  }
  SUBCASE("arriving along the normal: leaving, nf flipped towards the ray") {
    const HitFrame f = hit_frame(org, dir, 2.0, Vec3{0, 0, -1});
    CHECK_FALSE(f.entering);
    CHECK(f.nf == Vec3{0, 0, 1});
    CHECK(f.p_front.z > 1);
  }
  SUBCASE("a normal with no usable length faces the ray") {
    for (const Vec3& ng : {Vec3{0, 0, 0}, Vec3{1e300, 0, 0}, Vec3{std::nan(""), 0, 0}}) {
      const HitFrame f = hit_frame(org, dir, 2.0, ng);
      CHECK(f.nf == Vec3{0, 0, 1});  // -d
      CHECK(f.entering);
    }
  }
  SUBCASE("the offsets scale with the larger of the hit and the ray origin") {
    // Both hits at the origin: the offset is a float step, 1/65536 of the scale.
    const HitFrame near = hit_frame(Vec3{0, 0, 1e-3}, Vec3{0, 0, -1}, 1e-3, Vec3{0, 0, 1});
    const HitFrame far = hit_frame(Vec3{0, 0, 1e3}, Vec3{0, 0, -1}, 1e3, Vec3{0, 0, 1});
    CHECK(near.p_front.z == doctest::Approx(1e-3 / 65536));
    CHECK(far.p_front.z == doctest::Approx(1e3 / 65536));
    CHECK(far.p_back.z == doctest::Approx(-1e3 / 65536));
  }
}

}  // namespace
}  // namespace rayfarm
