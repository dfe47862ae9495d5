// StartShadowCaches: a shadow cache (EmbreeScene::ShadowCache) for each
// primitive shadow rays start on and each light they go to. A light's own
// cache holds the blocker of its last shadow ray, which serves the next ray
// when the two start side by side (eye rays' hits). Mirror rays' hits lie
// all over the scene, and their shadow rays, walked one by one, shared
// little with the light's last blocker; but rays that leave one tube for one
// light meet the same neighbours. Counted on rings, with every shadow ray
// from the second level on walked alone: the cache of the primitive it
// leaves blocked 2.67M of those 5.11M rays, the BVH 0.71M more, and 1.74M
// reached their light. Rings renders in 0.92x the time, balls 0.975x.
//
// The caches live in a fixed table, hashed: two keys in one entry only cost
// misses, since a cache changes no result (the exact test decides, whoever
// names the blocker). Entries name primitives of one scene, so the table is
// emptied when it serves another (use_for()).
#pragma once

#include <cstdint>
#include <vector>

#include "tracer/embree_scene.h"

namespace rayfarm {

class StartShadowCaches {
 public:
  using ShadowCache = EmbreeScene::ShadowCache;

  // Readies the table for `scene`: emptied unless it last served this scene.
  void use_for(const EmbreeScene& scene) {
    if (scene_serial_ == scene.serial() && !table_.empty()) return;
    table_.assign(size_t(1) << kBits, ShadowCache{});
    scene_serial_ = scene.serial();
  }

  // The cache of shadow rays that start on primitive `prim` of kind `geom`
  // (a TraceHit's) and go to light `light`. (Past 65,536 lights a key meets
  // the next primitive's: a collision, no more.)
  ShadowCache& at(uint32_t geom, uint32_t prim, uint32_t light) {
    const uint64_t key = ((uint64_t(prim) * EmbreeScene::kKinds + geom) << 16) + light;
    return table_[(key * kFibonacci) >> (64 - kBits)];
  }

 private:
  // 65,536 entries of 16 bytes (1 MiB a thread). Rings (12,601 primitives,
  // three lights: 37,803 keys) rendered in 0.983x, 0.942x, 0.921x, 0.929x
  // and 0.957x the time without the table with 2^10, 2^12, 2^14, 2^16 and
  // 2^18 entries (medians of 3, wavefronts of rows). With wavefronts of
  // tiles, 2^16 against 2^14: rings 0.974x (15 pairs, pinned), balls 1.008x,
  // mount 0.998x, gears 1.002x (9 pairs); 2^12 1.03x and 2^18 0.988x on rings.
  static constexpr int kBits = 16;
  static constexpr uint64_t kFibonacci = 0x9E3779B97F4A7C15ull;  // 2^64 / golden ratio: spreads near keys
  std::vector<ShadowCache> table_;
  uint64_t scene_serial_ = 0;
};

}  // namespace rayfarm
