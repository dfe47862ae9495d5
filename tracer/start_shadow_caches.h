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
// The caches live in a table of rows, a row per primitive and in it an entry
// per light, so that a point's shadow rays to its lights read one cache line
// or two, not one each. Where the scene's primitives times its lights fit
// the table's bound, each primitive has its own row; beyond it primitives
// are hashed to rows, and two in one row only cost misses, since a cache
// changes no result (the exact test decides, whoever names the blocker).
// Entries name primitives of one scene, so the table is emptied when it
// serves another (use_for()).
#pragma once

#include <algorithm>
#include <cassert>
#include <cstdint>
#include <vector>

#include "tracer/embree_scene.h"

namespace rayfarm {

class StartShadowCaches {
 public:
  using ShadowCache = EmbreeScene::ShadowCache;

  // At most `max_entries` caches (a test's bound; rendering keeps the default).
  explicit StartShadowCaches(uint64_t max_entries = kMaxEntries) : max_entries_(std::max<uint64_t>(max_entries, 1)) {}

  // Readies the table for `scene` and its `lights` lights: emptied unless it
  // last served this scene with as many lights. (Every wavefront asks, so
  // the common answer is "kept".)
  void use_for(const EmbreeScene& scene, uint32_t lights) {
    const uint32_t per_row = std::max(lights, 1u);  // a scene without lights keeps a row's worth
    if (scene_serial_ == scene.serial() && lights_ == per_row) return;  // serials start at 1
    lights_ = per_row;
    uint64_t primitives = 0;
    for (uint32_t k = 0; k < EmbreeScene::kKinds; ++k) {
      first_row_[k] = primitives;
      primitives += scene.primitive_count(EmbreeScene::Kind(k));
    }
    own_rows_ = primitives * lights_ <= max_entries_;
    // Hashed: the most rows that fit, a power of two (at least one).
    row_bits_ = own_rows_ ? 0 : 63 - __builtin_clzll(std::max<uint64_t>(max_entries_ / lights_, 1));
    const uint64_t rows = own_rows_ ? primitives : uint64_t(1) << row_bits_;
    table_.assign(size_t(rows * lights_), ShadowCache{});
    scene_serial_ = scene.serial();
  }

  // The cache of shadow rays that start on primitive `prim` of kind `geom`
  // (a TraceHit's) and go to light `light` (below use_for()'s `lights`).
  ShadowCache& at(uint32_t geom, uint32_t prim, uint32_t light) {
    assert(geom < EmbreeScene::kKinds && light < lights_);
    const size_t entry = row(geom, prim) * lights_ + light;
    assert(entry < table_.size());  // with rows of their own: prim below the kind's count
    return table_[entry];
  }

  // Whether each primitive has a row of its own (no two share an entry).
  bool own_rows() const { return own_rows_; }

 private:
  uint64_t row(uint32_t geom, uint32_t prim) const {
    if (own_rows_) return first_row_[geom] + prim;
    const uint64_t hash = (uint64_t(prim) * EmbreeScene::kKinds + geom) * kFibonacci;
    return row_bits_ == 0 ? 0 : hash >> (64 - row_bits_);
  }

  // 131,072 entries of 16 bytes (2 MiB a thread) at most. Rings (12,601
  // primitives, three lights: 604 KiB in rows of their own) rendered in
  // 0.987x the time of the table before, 65,536 entries hashed by primitive
  // and light (15 pairs, pinned); hashed by primitive, a row a primitive,
  // 0.991x (11 pairs). Before that: without the table, rings took 0.983x,
  // 0.942x, 0.921x, 0.929x and 0.957x the time with 2^10 to 2^18 entries
  // hashed by key (wavefronts of rows), and with tiles 2^16 entries 0.974x
  // that of 2^14.
  static constexpr uint64_t kMaxEntries = uint64_t(1) << 17;
  static constexpr uint64_t kFibonacci = 0x9E3779B97F4A7C15ull;  // 2^64 / golden ratio: spreads near keys
  uint64_t max_entries_;
  std::vector<ShadowCache> table_;
  uint64_t first_row_[EmbreeScene::kKinds] = {};  // per kind, the row of its primitive 0 (own rows)
  uint32_t lights_ = 1;
  bool own_rows_ = false;
  int row_bits_ = 0;  // hashed: 2^row_bits_ rows
  uint64_t scene_serial_ = 0;
};

}  // namespace rayfarm
