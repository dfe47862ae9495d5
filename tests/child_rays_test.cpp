// child_rays() (tracer/child_rays.h), and the child-ray kernel that shading
// runs instead: lane by lane the same bits at every width, with and without
// refraction, for random hits and the awkward ones (total internal
// reflection, grazing rays, a shading normal tilted from the geometric one).
#include <doctest/doctest.h>

#include <cmath>
#include <vector>

#include "tests/lane_widths.h"
#include "tracer/child_rays.h"
#include "tracer/hit_frame.h"

namespace rayfarm {
namespace {

struct Case {
  HitFrame frame;
  Vec3 ns;
  double eta;
};

RandomInputs random(23);

// Case k: a random hit's frame at scales from 1e-3 to 1e4, its shading
// normal nf or tilted, leaving glass (total internal reflection past the
// critical angle), entering it, or one of the edge cases.
Case case_for(int k) {
  const double scale = std::pow(10.0, random.uniform(-3, 4));
  Case c;
  c.frame = hit_frame(random.point(scale), random.point(1), random.uniform(0, 3), random.point(1));
  c.ns = c.frame.nf;
  c.eta = k % 2 ? 1.5 : 1 / 1.5;
  switch (k % 7) {
    case 0: c.ns = unit_or(c.frame.nf + random.point(0.3), c.frame.nf); break;  // a `pp` normal
    case 1: c.eta = random.uniform(0.3, 3); break;
    case 2: c.ns = unit_or(cross(c.frame.d, random.point(1)), c.frame.nf); break;  // grazing
    case 3: c.eta = 1; break;
    default: break;
  }
  return c;
}

void check_lanes(const std::vector<Case>& cases, bool refraction) {
  const int count = static_cast<int>(cases.size());
  for (const char* width : kLaneWidths) {
    CAPTURE(width);
    HitLanes frames{};
    alignas(64) double ns[3][HitLanes::kLanes] = {};
    ChildLanes out{};
    for (int i = 0; i < count; ++i) {
      const HitFrame& f = cases[i].frame;
      for (int c = 0; c < 3; ++c) {
        frames.d[c][i] = f.d[c], frames.nf[c][i] = f.nf[c];
        frames.p_front[c][i] = f.p_front[c], frames.p_back[c][i] = f.p_back[c];
        ns[c][i] = cases[i].ns[c];
      }
      out.eta[i] = cases[i].eta;
    }
    lane_kernels(width).child_rays(frames, ns, out, count, refraction);
    for (int i = 0; i < count; ++i) {
      CAPTURE(i);
      const HitFrame& f = cases[i].frame;
      const ChildRays want = child_rays(f.d, cases[i].ns, f.nf, f.p_front, f.p_back, cases[i].eta);
      const ChildRays got = child_lane(out, i);
      REQUIRE(same_bits(got.mirror_dir, want.mirror_dir));
      REQUIRE(same_bits(got.mirror_org, want.mirror_org));
      if (!refraction) {
        REQUIRE_FALSE(got.total_internal);
        continue;
      }
      REQUIRE(got.total_internal == want.total_internal);
      if (want.total_internal) continue;
      REQUIRE(same_bits(got.refract_dir, want.refract_dir));
      REQUIRE(same_bits(got.refract_org, want.refract_org));
    }
  }
}

TEST_CASE("child rays: the kernel gives child_rays()'s bits, lane by lane, at every width") {
  int total_internal = 0;
  for (int trial = 0; trial < 300; ++trial) {
    CAPTURE(trial);
    const int count = 1 + trial % HitLanes::kLanes;
    std::vector<Case> cases;
    for (int i = 0; i < count; ++i) {
      cases.push_back(case_for(trial + i));
      const Case& c = cases.back();
      total_internal += child_rays(c.frame.d, c.ns, c.frame.nf, c.frame.p_front, c.frame.p_back, c.eta).total_internal;
    }
    check_lanes(cases, true);
    check_lanes(cases, false);
  }
  CHECK(total_internal > 100);  // the cases reach the kernel's other branch
}

TEST_CASE("child rays: Snell's law, the mirror, and origins on the side each ray goes to") {
  // A ray at 45 degrees onto the plane z = 0 from above, normal +z.
  const HitFrame f = hit_frame(Vec3{-1, 0, 1}, Vec3{1, 0, -1}, 1.0, Vec3{0, 0, 1});
  SUBCASE("into glass: bent towards the normal, below the surface") {
    const ChildRays c = child_rays(f.d, f.nf, f.nf, f.p_front, f.p_back, 1 / 1.5);
    CHECK_FALSE(c.total_internal);
    const double sin_t = c.refract_dir.x / length(c.refract_dir);
    CHECK(sin_t == doctest::Approx(std::sqrt(0.5) / 1.5));
    CHECK(c.refract_org.z < 0);
    CHECK(c.mirror_dir.x == doctest::Approx(std::sqrt(0.5)));
    CHECK(c.mirror_dir.z == doctest::Approx(std::sqrt(0.5)));
    CHECK(c.mirror_org.z > 0);
  }
  SUBCASE("out of glass past the critical angle: total internal reflection") {
    CHECK(child_rays(f.d, f.nf, f.nf, f.p_front, f.p_back, 1.5).total_internal);
  }
}

}  // namespace
}  // namespace rayfarm
