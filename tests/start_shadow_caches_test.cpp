// StartShadowCaches: one cache per (start primitive, light), kept while it
// serves one scene and emptied for another, whose primitive numbers mean
// other things (a stale entry could name a primitive past its end).
#include <doctest/doctest.h>

#include "tracer/start_shadow_caches.h"

using namespace rayfarm;

namespace {

Scene two_spheres() {
  Scene s;
  s.camera.from = {0, 0, 10};
  s.camera.at = {0, 0, 0};
  s.camera.up = {0, 1, 0};
  s.materials.push_back(Material{});
  s.spheres.push_back({{0, 0, 0}, 1, 0});
  s.spheres.push_back({{3, 0, 0}, 1, 0});
  return s;
}

// Two spheres and a tube of two slices (8 radii long each, see
// EmbreeScene's cones): primitives of two kinds with the same numbers.
Scene spheres_and_tube() {
  Scene s = two_spheres();
  s.cones.push_back({{0, 3, 0}, 0.1, {1.6, 3, 0}, 0.1, 0});
  return s;
}

const EmbreeScene::Occluder kSecondSphere{EmbreeScene::kSpheres, 1};

}  // namespace

TEST_CASE("start shadow caches: each key keeps its own blocker, one scene at a time") {
  const Scene s = spheres_and_tube();
  const EmbreeScene first(s, EmbreeOptions{}), second(s, EmbreeOptions{});
  CHECK(first.serial() != second.serial());
  REQUIRE(first.primitive_count(EmbreeScene::kCones) == 2);

  StartShadowCaches caches;
  caches.use_for(first, 3);
  caches.at(EmbreeScene::kCones, 1, 2).remember(kSecondSphere);
  CHECK(caches.at(EmbreeScene::kCones, 1, 2).first == kSecondSphere);
  // Near keys (the next light, primitive or kind) land in other entries.
  CHECK(caches.at(EmbreeScene::kCones, 1, 1).first.geom == RTC_INVALID_GEOMETRY_ID);
  CHECK(caches.at(EmbreeScene::kCones, 0, 2).first.geom == RTC_INVALID_GEOMETRY_ID);
  CHECK(caches.at(EmbreeScene::kSpheres, 1, 2).first.geom == RTC_INVALID_GEOMETRY_ID);

  caches.use_for(first, 3);  // the same scene: kept
  CHECK(caches.at(EmbreeScene::kCones, 1, 2).first == kSecondSphere);
  caches.use_for(second, 3);  // another: emptied
  CHECK(caches.at(EmbreeScene::kCones, 1, 2).first.geom == RTC_INVALID_GEOMETRY_ID);
  caches.at(EmbreeScene::kSpheres, 1, 2).remember(kSecondSphere);
  caches.use_for(second, 2);  // other lights: emptied too
  CHECK(caches.at(EmbreeScene::kSpheres, 1, 1).first.geom == RTC_INVALID_GEOMETRY_ID);
  // A scene without lights (every wavefront still asks): kept like any other.
  caches.use_for(second, 0);
  caches.at(EmbreeScene::kSpheres, 1, 0).remember(kSecondSphere);
  caches.use_for(second, 0);
  CHECK(caches.at(EmbreeScene::kSpheres, 1, 0).first == kSecondSphere);
}

TEST_CASE("start shadow caches: a primitive's lights share a row, rows of their own while they fit") {
  // Twelve spheres and three lights: 36 keys.
  Scene s = two_spheres();
  for (int i = 2; i < 12; ++i) s.spheres.push_back({{3.0 * i, 0, 0}, 1, 0});
  const EmbreeScene scene(s, EmbreeOptions{});
  REQUIRE(scene.primitive_count(EmbreeScene::kSpheres) == 12);
  constexpr uint32_t kLights = 3;
  auto blocker = [](uint32_t prim, uint32_t light) {
    return EmbreeScene::Occluder{EmbreeScene::kSpheres, prim * kLights + light};  // a name per key
  };
  for (const uint64_t bound : {36u, 12u}) {
    CAPTURE(bound);
    StartShadowCaches caches(bound);
    caches.use_for(scene, kLights);
    CHECK(caches.own_rows() == (bound == 36));
    for (uint32_t prim = 0; prim < 12; ++prim) {
      for (uint32_t light = 1; light < kLights; ++light) {
        CHECK(&caches.at(EmbreeScene::kSpheres, prim, light) == &caches.at(EmbreeScene::kSpheres, prim, 0) + light);
      }
      for (uint32_t light = 0; light < kLights; ++light) {
        caches.at(EmbreeScene::kSpheres, prim, light).remember(blocker(prim, light));
      }
    }
    // With rows of their own every key keeps its blocker; hashed into 4 rows
    // (12 entries, each written last by one key: the hash spreads these 12
    // primitives over all 4 rows), 36 keys cannot.
    int kept = 0;
    for (uint32_t prim = 0; prim < 12; ++prim) {
      for (uint32_t light = 0; light < kLights; ++light) {
        kept += caches.at(EmbreeScene::kSpheres, prim, light).first == blocker(prim, light);
      }
    }
    CHECK(kept == (bound == 36 ? 36 : 12));
  }
}
