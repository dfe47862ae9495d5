// Rays inside a sphere (EmbreeScene::intersect_inside()): told which sphere
// they start inside, packets skip the walk and meet the sphere and what
// reaches into it; they must find what the walk finds, to the bit, at every
// kernel width: the sphere's far side, or a neighbour, triangle or tube
// that pokes in first, and rays said to be inside that are not.
#include <doctest/doctest.h>

#include <cmath>
#include <cstring>
#include <vector>

#include "lane_widths.h"
#include "tracer/embree_scene.h"

using namespace rayfarm;

namespace {

// Glass sphere 0 at the origin, radius 1, and what pokes into it: sphere 1
// touching it (overlapping by 1e-9, as mount's do), sphere 2 deep in, a
// triangle across its bottom and a tube through its side; sphere 3, of
// glass too, has seven small spheres poking in (too many to list); sphere
// 4 is opaque.
Scene glass_and_intruders() {
  Scene s;
  s.camera.from = {0.3, -6, 1};
  s.camera.at = {0, 0, 0};
  s.camera.up = {0, 0, 1};
  Material glass;
  glass.transmittance = 0.9;
  glass.ior = 1.5;
  s.materials = {glass, Material{}};
  s.spheres.push_back({{0, 0, 0}, 1, 0});
  s.spheres.push_back({{2 - 1e-9, 0, 0}, 1, 0});
  s.spheres.push_back({{0, 1.5, 0}, 0.7, 1});
  s.spheres.push_back({{10, 0, 0}, 1, 0});
  s.spheres.push_back({{-10, 0, 0}, 1, 1});
  for (int k = 0; k < 7; ++k) {
    const double a = 2 * M_PI * k / 7;
    s.spheres.push_back({{10 + std::cos(a), std::sin(a), 0}, 0.2, 1});
  }
  s.vertices = {{-0.9, -0.9, -0.7}, {0.9, -0.9, -0.8}, {0, 0.9, -0.75}};
  s.polygons.push_back({0, 3, false, 1});
  s.cones.push_back({{-2.5, 0, 0.3}, 0.15, {-0.4, 0, 0.3}, 0.15, 1});
  return s;
}

Vec3 unit(const Vec3& v) { return v * (1 / std::sqrt(dot(v, v))); }

bool same_hit(const TraceHit& a, const TraceHit& b) {
  if (a.geom != b.geom) return false;
  if (a.geom == RTC_INVALID_GEOMETRY_ID) return true;
  return a.prim == b.prim && same_bits(a.t, b.t) && same_bits(a.ng, b.ng) && same_bits(a.u, b.u) &&
         same_bits(a.v, b.v);
}

}  // namespace

TEST_CASE("sphere interiors: what reaches into a glass sphere is listed, when it is few") {
  const Scene s = glass_and_intruders();
  const EmbreeScene scene(s, EmbreeOptions{});
  // Sphere 1, sphere 2, the triangle, and the tube's slices near the sphere.
  CHECK(scene.intruder_count(0) >= 4);
  CHECK(scene.intruder_count(0) <= InteriorLaneShape::kMaxCaps);
  CHECK(scene.intruder_count(1) == 1);   // sphere 0 only
  CHECK(scene.intruder_count(3) == -1);  // seven intruders: walked
  CHECK(scene.intruder_count(2) == -1);  // opaque
  CHECK(scene.intruder_count(4) == -1);
  CHECK(scene.intruder_count(99) == -1);
  // A scene without glass lists nothing.
  Scene opaque = s;
  opaque.materials[0].transmittance = 0;
  CHECK(EmbreeScene(opaque, EmbreeOptions{}).intruder_count(0) == -1);
}

TEST_CASE("sphere interiors: packets inside a sphere find what the walk finds, at every width") {
  const Scene s = glass_and_intruders();
  for (const char* width : kLaneWidths) {
    CAPTURE(width);
    EmbreeOptions options;
    options.max_isa = width;
    const EmbreeScene scene(s, options);
    RandomInputs random(7);
    // What the rays should reach: points on the far side and on each
    // intruder, near where it pokes in.
    const std::vector<Vec3> aims = {{1, 0, 0},    {0.9, 0.1, -0.05}, {0, 0.85, 0}, {0.3, 0.8, 0.2},
                                    {0, 0, -0.75}, {0.4, -0.3, -0.78}, {-0.6, 0, 0.3}, {-0.9, 0.05, 0.25}};
    int met[EmbreeScene::kKinds] = {}, met_neighbour = 0, differ = 0, rays = 0;
    for (int packet = 0; packet < 400; ++packet) {
      const int count = 2 + packet % 15;
      Vec3 orgs[EmbreeScene::kPacket], dirs[EmbreeScene::kPacket];
      uint32_t inside[EmbreeScene::kPacket];
      for (int i = 0; i < count; ++i) {
        // Mostly inside, some on the surface, some outside though said to be inside.
        const double reach = packet % 5 == 4 && i % 3 == 0 ? 1.05 : 0.999;
        Vec3 o;
        do o = random.point(reach); while (dot(o, o) > reach * reach);
        if (packet % 7 == 0) o = unit(o) * 0.9999999;
        const Vec3 aim = packet % 2 ? aims[(packet / 2 + i) % aims.size()] + random.point(0.05) : random.point(1);
        orgs[i] = scene.to_local(o);  // the scene is camera-relative
        dirs[i] = aim - o;
        inside[i] = 0;
      }
      TraceHit told[EmbreeScene::kPacket], walked[EmbreeScene::kPacket];
      scene.intersect_packet(orgs, dirs, count, told, EmbreeScene::Origins::kScattered, nullptr, inside);
      scene.intersect_packet(orgs, dirs, count, walked, EmbreeScene::Origins::kScattered);
      for (int i = 0; i < count; ++i, ++rays) {
        differ += !same_hit(told[i], walked[i]);
        if (walked[i].geom < EmbreeScene::kKinds) ++met[walked[i].geom];
        met_neighbour += walked[i].geom == EmbreeScene::kSpheres && walked[i].prim != 0;
      }
    }
    CHECK(differ == 0);
    // The packets met every kind of intruder, not only the sphere's far side.
    CHECK(met[EmbreeScene::kTriangles] > rays / 50);
    CHECK(met[EmbreeScene::kCones] > rays / 50);
    CHECK(met_neighbour > rays / 50);
  }
}
