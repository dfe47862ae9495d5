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

const EmbreeScene::Occluder kSecondSphere{EmbreeScene::kSpheres, 1};

}  // namespace

TEST_CASE("start shadow caches: each key keeps its own blocker, one scene at a time") {
  const Scene s = two_spheres();
  const EmbreeScene first(s, EmbreeOptions{}), second(s, EmbreeOptions{});
  CHECK(first.serial() != second.serial());

  StartShadowCaches caches;
  caches.use_for(first);
  caches.at(EmbreeScene::kCones, 7, 2).remember(kSecondSphere);
  CHECK(caches.at(EmbreeScene::kCones, 7, 2).first == kSecondSphere);
  // Near keys (the next light, primitive or kind) land in other entries.
  CHECK(caches.at(EmbreeScene::kCones, 7, 1).first.geom == RTC_INVALID_GEOMETRY_ID);
  CHECK(caches.at(EmbreeScene::kCones, 8, 2).first.geom == RTC_INVALID_GEOMETRY_ID);
  CHECK(caches.at(EmbreeScene::kSpheres, 7, 2).first.geom == RTC_INVALID_GEOMETRY_ID);

  caches.use_for(first);  // the same scene: kept
  CHECK(caches.at(EmbreeScene::kCones, 7, 2).first == kSecondSphere);
  caches.use_for(second);  // another: emptied
  CHECK(caches.at(EmbreeScene::kCones, 7, 2).first.geom == RTC_INVALID_GEOMETRY_ID);
}
