// The study's converged reference, cached on disk: at 512x512 and 1024 spp it
// costs more than the rest of a study, and it depends only on the scene and
// its settings, so reruns load it. An entry is a float EXR plus a JSON sidecar
// in the layout `rayfarm render --stats` writes (width, height, spp, depth,
// rays, seconds), so a reference rendered by `rayfarm render --seed S+1` can
// be dropped in as well. Only uniform references are cached (no adaptive
// sampling, no cutoff, no robust traversal): the file name carries the rest.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "tracer/ray_stats.h"
#include "tracer/render_settings.h"

namespace rayfarm {

struct ReferenceImage {
  std::vector<float> rgb;  // width * height * 3 floats, as the renderer writes them
  double seconds = 0;        // render time when it was made
  double build_seconds = 0;  // BVH build time when it was made
  RayStats rays;
};

// <dir>/<scene>-<W>x<H>-spp<N>-depth<D>-seed<S>; ".exr" and ".json" are added.
std::string reference_cache_stem(const std::string& dir, const std::string& scene_name,
                                 const RenderSettings& settings);

// The cached reference, or nothing when a file is missing, the sidecar's
// numbers disagree with `settings`, or `scene_file` (if not empty) is newer
// than the image or another file than the sidecar's "scene" (a sidecar
// without one, from before, is taken). A corrupt entry throws InputError
// naming the file.
std::optional<ReferenceImage> load_cached_reference(const std::string& stem, const RenderSettings& settings,
                                                    const std::string& scene_file);

// Writes the entry (image first, sidecar last, so a half-written entry is
// never taken for a whole one: the sidecar is what load looks for), naming
// `scene_file` in the sidecar unless it is empty.
void store_reference(const std::string& stem, const RenderSettings& settings, const ReferenceImage& reference,
                     const std::string& scene_file);

}  // namespace rayfarm
