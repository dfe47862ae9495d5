// The lane kernels (tracer/lane_kernels.h) give, lane by lane, the bits of the
// scalar tests of shapes.h at every width this CPU runs: random rays, rays
// through vertices and edges, rays in a triangle's plane, tangent and
// zero-length rays, rays along a cone's axis and side, and segment ends
// exactly at the hit.
#include <doctest/doctest.h>

#include <cmath>
#include <vector>

#include "tests/lane_widths.h"
#include "tracer/lane_kernels.h"
#include "tracer/ray_lane_fill.h"
#include "tracer/shapes.h"

namespace rayfarm {
namespace {

constexpr int kLanes = RayLanes::kLanes;

struct Ray {
  Vec3 org, dir;
  double tfar;
};

// Packets of 16 rays each, grouped so that every packet shares its axes (as
// the triangle kernel needs), plus mixed packets for the sphere kernel.
std::vector<std::vector<Ray>> packets(const std::vector<Ray>& rays, bool by_axes) {
  std::vector<std::vector<Ray>> out, open(by_axes ? 6 : 1);  // by the largest axis and its sign
  for (const Ray& r : rays) {
    const ShearedRay s(r.org, r.dir);
    std::vector<Ray>& p = open[by_axes ? 2 * s.kz + (s.dir[s.kz] < 0) : 0];
    p.push_back(r);
    if (p.size() == kLanes) out.push_back(std::move(p)), p.clear();
  }
  return out;
}

RayLanes lanes_of(const std::vector<Ray>& packet) {
  RayLanes lanes;
  for (int i = 0; i < kLanes; ++i) set_ray_lane(lanes, i, ShearedRay(packet[i].org, packet[i].dir), packet[i].tfar);
  return lanes;
}

RandomInputs random(7);

// Rays at the triangle: random, through its vertices and edge midpoints (the
// watertight cases), in its plane (det = 0), and segments that end exactly
// where the scalar test finds the hit (t == tfar misses).
std::vector<Ray> rays_at_triangle(const Vec3& a, const Vec3& b, const Vec3& c) {
  std::vector<Ray> rays;
  const Vec3 targets[] = {a, b, c, 0.5 * (a + b), 0.5 * (b + c), 0.5 * (c + a), (a + b + c) * (1.0 / 3)};
  for (int k = 0; k < 400; ++k) {
    const Vec3 org = random.point(4);
    const Vec3 target = k % 3 == 0 ? random.point(2) : targets[k % 7];
    double tfar = k % 5 == 0 ? random.uniform(0.2, 1.5) : HUGE_VAL;
    TriangleHit hit;
    if (k % 11 == 0 && intersect_triangle(ShearedRay(org, target - org), a, b, c, 0, HUGE_VAL, hit)) tfar = hit.t;
    rays.push_back({org, target - org, tfar});
  }
  for (int k = 0; k < 64; ++k) {  // in the plane, through the centre
    const Vec3 along = (k % 2 ? b - a : c - a) * random.uniform(0.5, 2.0);
    rays.push_back({(a + b + c) * (1.0 / 3) - along, along, HUGE_VAL});
  }
  return rays;
}

std::vector<Ray> rays_at_sphere(const Vec3& center, double radius) {
  std::vector<Ray> rays;
  for (int k = 0; k < 400; ++k) {
    const Vec3 org = k % 7 == 0 ? center + random.point(radius * 0.5) : random.point(4);  // some from inside
    Vec3 target = center + random.point(radius * 1.5);
    if (k % 5 == 0) {  // tangent: aimed at a point on the silhouette
      const Vec3 to = center - org, side = cross(to, Vec3{0.3, 1, 0.2});
      target = center + side * (radius / length(side));
    }
    const Vec3 dir = k % 37 == 0 ? Vec3{} : target - org;  // zero-length rays miss
    double tfar = k % 3 == 0 ? random.uniform(0.3, 1.2) : HUGE_VAL;
    ShapeHit hit;
    if (k % 13 == 0 && intersect_sphere(center, radius, org, dir, 0, HUGE_VAL, hit)) tfar = hit.t;
    rays.push_back({org, dir, tfar});
  }
  return rays;
}

// Rays at the cone: random, from inside, tangent to its side, parallel to
// its axis (a cylinder's side is then missed) and to a generating line (one
// root), zero-length, and segments that end exactly at the scalar test's hit.
std::vector<Ray> rays_at_cone(const ConeShape& cone) {
  std::vector<Ray> rays;
  const Vec3 side = normalize(cross(cone.axis, Vec3{0.3, 1, 0.2}));  // a unit vector across the axis
  const double reach = cone.half_length + cone.max_radius();
  for (int k = 0; k < 400; ++k) {
    Vec3 org = k % 7 == 0 ? cone.center + random.point(cone.mid_radius * 0.5) : random.point(4);
    Vec3 dir = cone.center + random.point(reach) - org;
    if (k % 5 == 0) {  // tangent: aimed at a point on the silhouette
      const double s = random.uniform(-cone.half_length, cone.half_length);
      const Vec3 across = normalize(cross(cone.center - org, cone.axis));
      dir = cone.center + s * cone.axis + (cone.mid_radius + cone.slope * s) * across - org;
    } else if (k % 5 == 1) {  // along a generating line, from beside or inside the side
      const Vec3 base = cone.base() + (cone.mid_radius - cone.slope * cone.half_length) * side;
      const Vec3 apex = cone.apex() + (cone.mid_radius + cone.slope * cone.half_length) * side;
      org = base + random.point(cone.mid_radius) - 2 * (apex - base);
      dir = (k % 2 ? 1.0 : -1.0) * (apex - base);
    } else if (k % 5 == 2) {  // parallel to the axis
      org = cone.center + random.point(cone.mid_radius * 1.5) - 3 * reach * cone.axis;
      dir = cone.axis * random.uniform(0.5, 2);
    }
    if (k % 37 == 0) dir = Vec3{};  // zero-length rays miss
    double tfar = k % 3 == 0 ? random.uniform(0.3, 1.2) : HUGE_VAL;
    ShapeHit hit;
    if (k % 13 == 0 && intersect_cone(cone, org, dir, 0, HUGE_VAL, hit)) tfar = hit.t;
    rays.push_back({org, dir, tfar});
  }
  return rays;
}

// A cone between random ends: cylinders, cones, pointed cones, thin long
// tubes, and a degenerate one with both ends at one point.
ConeShape random_cone(int trial) {
  const Vec3 base = random.point(1);
  const Vec3 apex = trial % 10 == 0 ? base : base + random.point(trial % 4 == 0 ? 3 : 1);
  const double r0 = random.uniform(0.01, 0.8);
  const double r1 = trial % 3 == 0 ? r0 : (trial % 3 == 1 ? 0 : random.uniform(0.01, 0.8));
  return ConeShape::make(base, r0, apex, trial % 4 == 0 ? r0 * 0.05 : r1);
}

}  // namespace

// Packets whose rays share their axes, and mixed ones, run class by class
// (axis_classes()) as the callbacks run them.
TEST_CASE("lane kernels: the triangle kernel gives intersect_triangle()'s bits at every width") {
  int mixed = 0;
  for (int trial = 0; trial < 40; ++trial) {
    const Vec3 a = random.point(2), b = random.point(2), c = trial % 8 == 0 ? 0.5 * (a + b) : random.point(2);
    for (const bool by_axes : {true, false}) {
      for (const auto& packet : packets(rays_at_triangle(a, b, c), by_axes)) {
        const RayLanes lanes = lanes_of(packet);
        const double A[3] = {a.x, a.y, a.z}, B[3] = {b.x, b.y, b.z}, C[3] = {c.x, c.y, c.z};
        const uint32_t active = trial % 2 ? 0xFFFFu : 0x5A3Cu;  // some lanes off
        AxisClass classes[kAxisClasses];
        const int n = axis_classes(lanes, active, classes);
        if (by_axes) REQUIRE(n == 1);
        mixed += n > 1;
        for (const char* width : kLaneWidths) {
          CAPTURE(width);
          TriangleLaneHits out[kAxisClasses];
          uint32_t bits = 0, lane_class[kLanes] = {};
          for (int k = 0; k < n; ++k) {
            bits |= lane_kernels(width).triangle(lanes, classes[k], A, B, C, out[k]);
            for (int i = 0; i < kLanes; ++i) lane_class[i] = (classes[k].lanes >> i) & 1 ? k : lane_class[i];
          }
          for (int i = 0; i < kLanes; ++i) {
            TriangleHit hit;
            const bool scalar = intersect_triangle(ShearedRay(packet[i].org, packet[i].dir), a, b, c, 0,
                                                   packet[i].tfar, hit);
            const bool lane = (bits >> i) & 1;
            REQUIRE(lane == (scalar && ((active >> i) & 1)));
            if (!lane) continue;
            const TriangleLaneHits& o = out[lane_class[i]];
            CHECK(same_bits(o.t[i], hit.t));
            CHECK(same_bits(o.v[i] / o.det[i], hit.u));
            CHECK(same_bits(o.w[i] / o.det[i], hit.v));
          }
        }
      }
    }
  }
  CHECK(mixed > 20);
}

TEST_CASE("lane kernels: the sphere kernel gives intersect_sphere()'s bits at every width") {
  size_t hits = 0, misses = 0;
  for (int trial = 0; trial < 40; ++trial) {
    const Vec3 center = random.point(1);
    const double radius = trial % 10 == 0 ? 0 : random.uniform(0.01, 1.5);
    for (const auto& packet : packets(rays_at_sphere(center, radius), false)) {
      const RayLanes lanes = lanes_of(packet);
      const double C[3] = {center.x, center.y, center.z};
      for (const char* width : kLaneWidths) {
        CAPTURE(width);
        alignas(64) double t[kLanes];
        const uint32_t active = trial % 2 ? 0xFFFFu : 0xC3A5u;
        const uint32_t bits = lane_kernels(width).sphere(lanes, active, C, radius, t);
        for (int i = 0; i < kLanes; ++i) {
          ShapeHit hit;
          const bool scalar = intersect_sphere(center, radius, packet[i].org, packet[i].dir, 0, packet[i].tfar, hit);
          const bool lane = (bits >> i) & 1;
          REQUIRE(lane == (scalar && ((active >> i) & 1)));
          if (lane) CHECK(same_bits(t[i], hit.t));
          (lane ? hits : misses) += 1;
        }
      }
    }
  }
  CHECK(hits > 1000);  // both outcomes well represented
  CHECK(misses > 1000);
}

TEST_CASE("lane kernels: the cone kernel gives intersect_cone()'s bits at every width, whole and sliced") {
  size_t hits = 0, misses = 0, sliced_hits = 0;
  for (int trial = 0; trial < 60; ++trial) {
    const ConeShape cone = random_cone(trial);
    // The whole cone, or a slice: open below, open above, or closed.
    double s_lo = -HUGE_VAL, s_hi = HUGE_VAL;
    if (trial % 3 != 0) {
      const double cut = random.uniform(-cone.half_length, cone.half_length);
      (trial % 3 == 1 ? s_hi : s_lo) = cut;
      if (trial % 6 == 5) s_hi = cut + 0.5 * (cone.half_length - cut);
    }
    const ConeLaneShape shape{{cone.center.x, cone.center.y, cone.center.z},
                              {cone.axis.x, cone.axis.y, cone.axis.z},
                              cone.half_length,
                              cone.mid_radius,
                              cone.slope,
                              cone.bound2,
                              cone.rmax2,
                              s_lo,
                              s_hi};
    for (const auto& packet : packets(rays_at_cone(cone), false)) {
      const RayLanes lanes = lanes_of(packet);
      for (const char* width : kLaneWidths) {
        CAPTURE(width);
        CAPTURE(trial);
        ConeLaneHits out;
        const uint32_t active = trial % 2 ? 0xFFFFu : 0xA5C3u;
        const uint32_t bits = lane_kernels(width).cone(lanes, active, shape, out);
        for (int i = 0; i < kLanes; ++i) {
          ShapeHit hit;
          const bool scalar = intersect_cone(cone, packet[i].org, packet[i].dir, 0, packet[i].tfar, hit, s_lo, s_hi);
          const bool lane = (bits >> i) & 1;
          REQUIRE(lane == (scalar && ((active >> i) & 1)));
          if (lane) {
            CHECK(same_bits(out.t[i], hit.t));
            CHECK(same_bits(lane_vec(out.normal, i), hit.normal));
            sliced_hits += trial % 3 != 0;
          }
          (lane ? hits : misses) += 1;
        }
      }
    }
  }
  CHECK(hits > 1000);  // both outcomes well represented
  CHECK(misses > 1000);
  CHECK(sliced_hits > 300);
}

// Each lane its own primitive, as the start caches of rays walked one by one
// run them (EmbreeScene::occluded_alone()): lane i's ray is one of the rays
// at primitive i, so a lane that read another lane's primitive would miss
// where its scalar test hits.
TEST_CASE("lane kernels: the per-lane sphere and cone kernels give each lane's own primitive's bits at every width") {
  size_t hits = 0, misses = 0;
  for (int trial = 0; trial < 20; ++trial) {
    Vec3 centers[kLanes];
    double radii[kLanes];
    ConeShape cones[kLanes];
    double s_lo[kLanes], s_hi[kLanes];
    SphereLaneShapes sphere_lanes;
    ConeLaneShapes cone_lanes;
    std::vector<Ray> at_sphere[kLanes], at_cone[kLanes];
    for (int i = 0; i < kLanes; ++i) {
      centers[i] = random.point(1);
      radii[i] = (trial + i) % 10 == 0 ? 0 : random.uniform(0.01, 1.5);
      const double c[3] = {centers[i].x, centers[i].y, centers[i].z};
      set_sphere_lane(sphere_lanes, i, c, radii[i]);
      at_sphere[i] = rays_at_sphere(centers[i], radii[i]);
      cones[i] = random_cone(trial * kLanes + i);
      const ConeShape& k = cones[i];
      s_lo[i] = i % 3 == 1 ? random.uniform(-k.half_length, k.half_length) : -HUGE_VAL;  // some slices
      s_hi[i] = i % 3 == 2 ? random.uniform(-k.half_length, k.half_length) : HUGE_VAL;
      set_cone_lane(cone_lanes, i,
                    {{k.center.x, k.center.y, k.center.z}, {k.axis.x, k.axis.y, k.axis.z}, k.half_length,
                     k.mid_radius, k.slope, k.bound2, k.rmax2, s_lo[i], s_hi[i]});
      at_cone[i] = rays_at_cone(k);
    }
    for (int p = 0; p < 25; ++p) {
      std::vector<Ray> sphere_packet, cone_packet;
      for (int i = 0; i < kLanes; ++i) {
        sphere_packet.push_back(at_sphere[i][(p * 17 + i) % at_sphere[i].size()]);
        cone_packet.push_back(at_cone[i][(p * 17 + i) % at_cone[i].size()]);
      }
      const RayLanes sphere_rays = lanes_of(sphere_packet), cone_rays = lanes_of(cone_packet);
      const uint32_t active = p % 2 ? 0xFFFFu : 0x5AC3u;
      for (const char* width : kLaneWidths) {
        CAPTURE(width);
        alignas(64) double t[kLanes];
        ConeLaneHits out;
        const uint32_t sphere_bits = lane_kernels(width).sphere_per_lane(sphere_rays, active, sphere_lanes, t);
        const uint32_t cone_bits = lane_kernels(width).cone_per_lane(cone_rays, active, cone_lanes, out);
        for (int i = 0; i < kLanes; ++i) {
          const Ray& rs = sphere_packet[i];
          const Ray& rc = cone_packet[i];
          ShapeHit sphere_hit, cone_hit;
          const bool on = (active >> i) & 1;
          const bool sphere = on && intersect_sphere(centers[i], radii[i], rs.org, rs.dir, 0, rs.tfar, sphere_hit);
          const bool cone = on && intersect_cone(cones[i], rc.org, rc.dir, 0, rc.tfar, cone_hit, s_lo[i], s_hi[i]);
          REQUIRE(((sphere_bits >> i) & 1) == sphere);
          REQUIRE(((cone_bits >> i) & 1) == cone);
          if (sphere) CHECK(same_bits(t[i], sphere_hit.t));
          if (cone) {
            CHECK(same_bits(out.t[i], cone_hit.t));
            CHECK(same_bits(lane_vec(out.normal, i), cone_hit.normal));
          }
          hits += sphere + cone;
          misses += !sphere + !cone;
        }
      }
    }
  }
  CHECK(hits > 1000);  // both outcomes well represented
  CHECK(misses > 1000);
}

// Directions with ties between |components|, zero and negative components,
// and values that float rounding moves (so rounding first matters).
Vec3 awkward_direction(int k) {
  switch (k % 6) {
    case 0: return {1, 1, 1};
    case 1: return {-1, 0, 1};
    case 2: return {0, -0.0, 0};
    case 3: return {0.1, -0.3, -0.3};
    case 4: return {-2, 1 + 1e-12, -1e-300};
    default: return random.point(3);
  }
}

TEST_CASE("lane kernels: the fill kernel gives set_ray_lane()'s lanes of the float-rounded rays at every width") {
  for (int trial = 0; trial < 200; ++trial) {
    const int count = 1 + trial % kLanes;
    std::vector<Vec3> orgs, dirs;
    for (int i = 0; i < count; ++i) {
      orgs.push_back(random.point(1e3));
      dirs.push_back(trial % 3 ? random.point(2) : awkward_direction(trial + i));
    }
    if (trial % 7 == 0) dirs.assign(count, dirs[0]);  // one shared direction
    const double tfar = trial % 2 ? HUGE_VAL : 1.0;
    RayLanes expected;
    for (int i = 0; i < kLanes; ++i) {
      const int from = i < count ? i : 0;  // disabled lanes repeat ray 0
      const Vec3 o = orgs[from], d = dirs[from];
      const Vec3 fo{float(o.x), float(o.y), float(o.z)}, fd{float(d.x), float(d.y), float(d.z)};
      set_ray_lane(expected, i, ShearedRay(fo, fd), tfar);
    }
    for (const char* width : kLaneWidths) {
      CAPTURE(width);
      CAPTURE(trial);
      RayLanes lanes;
      alignas(64) FloatLanes floats;
      REQUIRE(lane_kernels(width).fill(&orgs[0].x, &dirs[0].x, count, tfar, lanes, floats));
      CHECK(lanes.z_is_x == expected.z_is_x);
      CHECK(lanes.z_is_y == expected.z_is_y);
      CHECK(lanes.flipped == expected.flipped);
      for (int i = 0; i < kLanes; ++i) {
        for (int c = 0; c < 3; ++c) {
          REQUIRE(same_bits(lanes.org[c][i], expected.org[c][i]));
          REQUIRE(same_bits(lanes.dir[c][i], expected.dir[c][i]));
          REQUIRE(same_bits(floats.org[c][i], expected.org[c][i]));  // exact in double
          REQUIRE(same_bits(floats.dir[c][i], expected.dir[c][i]));
        }
        REQUIRE(same_bits(lanes.sx[i], expected.sx[i]));
        REQUIRE(same_bits(lanes.sy[i], expected.sy[i]));
        REQUIRE(same_bits(lanes.sz[i], expected.sz[i]));
        REQUIRE(same_bits(lanes.tfar[i], tfar));
        const ShearedRay back = lane_ray(lanes, i), scalar(lane_org(expected, i), lane_dir(expected, i));
        REQUIRE(back.kx == scalar.kx);
        REQUIRE(back.ky == scalar.ky);
        REQUIRE(back.kz == scalar.kz);
      }
    }
  }
}

TEST_CASE("lane kernels: the fill kernel refuses a ray Embree cannot take, in any lane, at every width") {
  const double kNaN = std::nan("");
  for (const char* width : kLaneWidths) {
    CAPTURE(width);
    for (int lane = 0; lane < kLanes; lane += 5) {
      for (const double bad : {kNaN, 2e18, -1e300}) {
        for (const bool in_dir : {false, true}) {
          std::vector<Vec3> orgs(kLanes, Vec3{1, 2, 3}), dirs(kLanes, Vec3{0.1, -0.2, 1});
          (in_dir ? dirs : orgs)[lane].y = bad;
          RayLanes lanes;
          alignas(64) FloatLanes floats;
          CHECK_FALSE(lane_kernels(width).fill(&orgs[0].x, &dirs[0].x, kLanes, 1.0, lanes, floats));
          // A bad ray past `count` is not the packet's: the lane repeats ray 0.
          if (lane > 0) CHECK(lane_kernels(width).fill(&orgs[0].x, &dirs[0].x, lane, 1.0, lanes, floats));
        }
      }
    }
    std::vector<Vec3> edge(kLanes, Vec3{kMaxRayComponent, -kMaxRayComponent, 0});
    RayLanes lanes;
    alignas(64) FloatLanes floats;
    CHECK(lane_kernels(width).fill(&edge[0].x, &edge[0].x, kLanes, 1.0, lanes, floats));
  }
}

TEST_CASE("lane kernels: axis classes put every active lane in one class, with its ray's axes") {
  std::vector<Ray> packet(kLanes, Ray{{0, 0, 0}, {0.1, 0.2, 1}, HUGE_VAL});
  packet[9].dir = {0.1, 0.2, -1};  // same axis, other sign: kx and ky swap
  packet[3].dir = {2, 0.2, 1};
  packet[4].dir = {-0.3, 1, 1};    // a tie: z wins, as in ShearedRay
  const RayLanes lanes = lanes_of(packet);
  for (const uint32_t active : {0xFFFFu, 0xFDF7u, 0x0200u, 0u}) {
    CAPTURE(active);
    AxisClass classes[kAxisClasses];
    const int n = axis_classes(lanes, active, classes);
    uint32_t seen = 0;
    for (int k = 0; k < n; ++k) {
      REQUIRE(classes[k].lanes != 0);
      CHECK((seen & classes[k].lanes) == 0);
      seen |= classes[k].lanes;
      for (uint32_t bits = classes[k].lanes; bits; bits &= bits - 1) {
        const ShearedRay ray(packet[__builtin_ctz(bits)].org, packet[__builtin_ctz(bits)].dir);
        CHECK(classes[k].kx == ray.kx);
        CHECK(classes[k].ky == ray.ky);
        CHECK(classes[k].kz == ray.kz);
      }
    }
    CHECK(seen == active);
  }
  AxisClass classes[kAxisClasses];
  CHECK(axis_classes(lanes, 0xFFFFu, classes) == 3);
  CHECK(axis_classes(lanes, 0x0001u, classes) == 1);
}

}  // namespace rayfarm
