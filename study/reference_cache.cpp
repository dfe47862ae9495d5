// Reference cache entries: <stem>.exr (float RGB) and <stem>.json (sidecar).
#include "study/reference_cache.h"

#include <filesystem>

#include "tracer/error.h"
#include "tracer/image_io.h"
#include "tracer/render_job.h"
#include "tracer/text_file.h"

namespace rayfarm {

namespace {

namespace fs = std::filesystem;

// A sidecar is a few hundred bytes. Read with a limit, one that is a link to
// a device (/dev/zero) or a huge file is refused at once as corrupt, not read
// until memory runs out.
constexpr size_t kMaxSidecarBytes = 1 << 20;

// A value from the sidecar, with the file and key in the error.
template <class T>
T sidecar_value(const nlohmann::json& j, const std::string& path, const char* a, const char* b = nullptr) {
  const std::string key = b ? std::string(a) + "." + b : std::string(a);
  try {
    return b ? j.at(a).at(b).get<T>() : j.at(a).get<T>();
  } catch (const nlohmann::json::exception&) {
    throw InputError(path + ": missing or malformed key " + key);
  }
}

bool newer(const std::string& a, const std::string& b) {
  std::error_code ec;
  const auto ta = fs::last_write_time(a, ec);
  if (ec) return false;
  const auto tb = fs::last_write_time(b, ec);
  return !ec && ta > tb;
}

// The file name is the scene's name only: a/balls.nff and b/balls.nff share
// it, so the sidecar names the file too.
bool same_file(const std::string& a, const std::string& b) {
  std::error_code ec;
  return fs::equivalent(a, b, ec) && !ec;
}

}  // namespace

std::string reference_cache_stem(const std::string& dir, const std::string& scene_name,
                                 const RenderSettings& s) {
  const std::string name = scene_name + "-" + std::to_string(s.width) + "x" + std::to_string(s.height) + "-spp" +
                           std::to_string(s.spp) + "-depth" + std::to_string(s.max_depth) + "-seed" +
                           std::to_string(s.seed);
  return (fs::path(dir) / name).string();
}

std::optional<ReferenceImage> load_cached_reference(const std::string& stem, const RenderSettings& s,
                                                    const std::string& scene_file) {
  const std::string image = stem + ".exr", sidecar = stem + ".json";
  if (!fs::exists(image) || !fs::exists(sidecar)) return std::nullopt;
  if (!scene_file.empty() && newer(scene_file, image)) return std::nullopt;
  const nlohmann::json j = read_json_file(sidecar, kMaxSidecarBytes);
  if (!scene_file.empty() && j.contains("scene") &&
      !same_file(sidecar_value<std::string>(j, sidecar, "scene"), scene_file))
    return std::nullopt;
  const bool same = sidecar_value<int>(j, sidecar, "width") == s.width &&
                    sidecar_value<int>(j, sidecar, "height") == s.height &&
                    sidecar_value<int>(j, sidecar, "spp") == s.spp &&
                    sidecar_value<int>(j, sidecar, "depth") == s.max_depth &&
                    (!j.contains("seed") || sidecar_value<uint64_t>(j, sidecar, "seed") == s.seed);
  if (!same) return std::nullopt;
  RgbImage rgb = read_image(image);
  if (rgb.width != s.width || rgb.height != s.height) {
    throw InputError(image + ": " + std::to_string(rgb.width) + "x" + std::to_string(rgb.height) +
                     " does not match its sidecar");
  }
  ReferenceImage ref;
  ref.rgb = std::move(rgb.rgb);
  ref.seconds = sidecar_value<double>(j, sidecar, "seconds", "render");
  ref.build_seconds = sidecar_value<double>(j, sidecar, "seconds", "build");
  ref.rays.eye = sidecar_value<uint64_t>(j, sidecar, "rays", "eye");
  ref.rays.eye_hit = sidecar_value<uint64_t>(j, sidecar, "rays", "eye_hit");
  ref.rays.shadow = sidecar_value<uint64_t>(j, sidecar, "rays", "shadow");
  ref.rays.reflection = sidecar_value<uint64_t>(j, sidecar, "rays", "reflection");
  ref.rays.refraction = sidecar_value<uint64_t>(j, sidecar, "rays", "refraction");
  // `rayfarm render --stats` names the raw count non_finite_samples.
  if (j.contains("non_finite_samples")) ref.rays.non_finite = sidecar_value<uint64_t>(j, sidecar, "non_finite_samples");
  return ref;
}

void store_reference(const std::string& stem, const RenderSettings& s, const ReferenceImage& ref,
                     const std::string& scene_file) {
  fs::create_directories(fs::path(stem).parent_path());
  write_image(stem + ".exr", s.width, s.height, ref.rgb);
  nlohmann::json j = {
      {"width", s.width},
      {"height", s.height},
      {"spp", s.spp},
      {"depth", s.max_depth},
      {"seed", s.seed},
      {"rays", ray_counts_json(ref.rays)},
      {"non_finite_samples", ref.rays.non_finite},
      {"seconds", {{"render", ref.seconds}, {"build", ref.build_seconds}}}};
  if (!scene_file.empty()) j["scene"] = fs::absolute(scene_file).lexically_normal().string();
  write_json_file(stem + ".json", j);
}

}  // namespace rayfarm
