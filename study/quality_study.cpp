// The accuracy-vs-time study: one Renderer per knob setting, timed, compared
// with a converged reference and, where the sweep has one, with its exact
// member at the same sample positions.
#include "study/quality_study.h"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <utility>

#include "study/pareto.h"
#include "study/reference_cache.h"
#include "study/study_knobs.h"
#include "tracer/error.h"
#include "tracer/image_io.h"
#include "tracer/renderer.h"

namespace rayfarm {

namespace {

using Clock = std::chrono::steady_clock;

struct Rendered {
  std::vector<float> rgb;
  StudyRow row;
};

void require(bool ok, const std::string& what) {
  if (!ok) throw InputError("study: " + what);
}

std::string format(const char* fmt, double value) {
  char buf[128];
  std::snprintf(buf, sizeof buf, fmt, value);
  return buf;
}

constexpr int kMaxRuns = 10;

// Renders `repeats` times or more (see StudyOptions::min_timed_seconds) with
// one Renderer, so one BVH build, and keeps the fastest time; the image and
// ray counts are those of the first run.
Rendered render(const Scene& scene, const RenderSettings& settings, int repeats, double min_seconds) {
  Rendered out;
  out.row.settings = settings;
  const Renderer renderer(scene, settings);
  out.row.build_seconds = renderer.build_seconds();
  std::vector<float> again;
  double total = 0;
  for (int i = 0; i < std::max(1, repeats) || (total < min_seconds && i < kMaxRuns); ++i) {
    RayStats rays;
    const auto t0 = Clock::now();
    renderer.render_rows(0, settings.height, i == 0 ? out.rgb : again, &rays);
    const double seconds = std::chrono::duration<double>(Clock::now() - t0).count();
    total += seconds;
    out.row.runs = i + 1;
    if (i == 0) {
      out.row.rays = rays;
      out.row.seconds = seconds;
    } else {
      out.row.seconds = std::min(out.row.seconds, seconds);
    }
  }
  out.row.non_finite = out.row.rays.non_finite;
  return out;
}

// Runs the renders, reuses a render whose settings were already rendered, and
// reports progress; owns the numbering "[i/n]".
class StudyRunner {
 public:
  StudyRunner(const Scene& scene, const StudyOptions& options, const StudyProgress& progress, size_t total)
      : scene_(scene), options_(options), progress_(progress), total_(total), start_(Clock::now()) {}

  // The render for `settings`, from an earlier row when one had them.
  const Rendered& run(const RenderSettings& settings, const std::string& label, int repeats, double min_seconds) {
    ++done_;
    const std::string key = settings_key(settings);
    if (const auto it = done_renders_.find(key); it != done_renders_.end()) {
      say(label + ": same settings as " + it->second.row.sweep + " " + it->second.row.value + ", reused");
      return it->second;
    }
    say(label + " ...");
    Rendered r = render(scene_, settings, repeats, min_seconds);
    say("  " + label + ": " + format("%.3f s", r.row.seconds) + " (fastest of " + std::to_string(r.row.runs) + "), " +
        std::to_string(r.row.rays.total()) + " rays");
    if (r.row.non_finite > 0) {
      say("  warning: " + std::to_string(r.row.non_finite) + " non-finite values in " + label);
    }
    return done_renders_.emplace(key, std::move(r)).first->second;
  }

  void remember(const std::string& sweep, const std::string& value, const RenderSettings& settings) {
    Rendered& r = done_renders_.at(settings_key(settings));
    if (r.row.sweep.empty()) {
      r.row.sweep = sweep;
      r.row.value = value;
    }
  }

  // Writes the image as out_dir/name when images are wanted.
  void keep_image(const std::vector<float>& rgb, const RenderSettings& s, const std::string& name,
                  StudyResult& result) const {
    if (!options_.write_images) return;
    std::filesystem::create_directories(options_.out_dir);
    write_image((std::filesystem::path(options_.out_dir) / name).string(), s.width, s.height, rgb);
    result.images.push_back(name);
  }

  void say(const std::string& line) const {
    if (!progress_) return;
    const double elapsed = std::chrono::duration<double>(Clock::now() - start_).count();
    progress_("study: " + options_.scene_name + " [" + std::to_string(done_) + "/" + std::to_string(total_) + ", " +
              format("%.0f s] ", elapsed) + line);
  }

  void count_one() { ++done_; }

 private:
  const Scene& scene_;
  const StudyOptions& options_;
  const StudyProgress& progress_;
  size_t total_ = 0;
  size_t done_ = 0;
  Clock::time_point start_;
  std::map<std::string, Rendered> done_renders_;
};

// The cache's entry for `s`, or nothing. A corrupt one (a truncated sidecar, an
// image that is no EXR) is reported and rendered again, which rewrites it: it
// stopped the study, though the cache only saves time and deleting the entry
// by hand led to the same render.
std::optional<ReferenceImage> cached_reference(const std::string& stem, const RenderSettings& s,
                                               const StudyOptions& o, const StudyRunner& runner) {
  try {
    return load_cached_reference(stem, s, o.scene_file);
  } catch (const InputError& e) {
    runner.say(std::string("warning: cached reference unreadable: ") + e.what() +
               "; rendering it again (the entry is rewritten)");
    return std::nullopt;
  }
}

// The converged reference, from the cache when it has it: many jittered
// samples at the reference depth, from an independent seed so that no sweep
// shares its sample positions.
Rendered reference_render(const RenderSettings& base, const StudyOptions& o, StudyRunner& runner,
                          StudyResult& result) {
  RenderSettings s = base;
  s.spp = o.reference_spp;
  s.max_depth = o.reference_depth;
  s.seed = o.seed + 1;
  const std::string label = "reference " + std::to_string(s.spp) + " spp, depth " + std::to_string(s.max_depth);
  const std::string stem =
      o.reference_cache.empty() ? std::string() : reference_cache_stem(o.reference_cache, o.scene_name, s);
  Rendered ref;
  ref.row.sweep = "reference";
  ref.row.value = std::to_string(s.spp);
  ref.row.settings = s;
  if (!stem.empty()) {
    if (std::optional<ReferenceImage> cached = cached_reference(stem, s, o, runner)) {
      runner.count_one();
      runner.say(label + ": from " + stem + ".exr");
      ref.rgb = std::move(cached->rgb);
      ref.row.seconds = cached->seconds;
      ref.row.build_seconds = cached->build_seconds;
      ref.row.rays = cached->rays;
      ref.row.non_finite = cached->rays.non_finite;
      result.reference_cached = true;
      return ref;
    }
  }
  const Rendered& fresh = runner.run(s, label, 1, 0);
  ref.rgb = fresh.rgb;
  ref.row.seconds = fresh.row.seconds;
  ref.row.build_seconds = fresh.row.build_seconds;
  ref.row.rays = fresh.row.rays;
  ref.row.non_finite = fresh.row.non_finite;
  if (!stem.empty()) {
    store_reference(stem, s, {ref.rgb, ref.row.seconds, ref.row.build_seconds, ref.row.rays}, o.scene_file);
    runner.say("  cached as " + stem + ".exr");
  }
  return ref;
}

// Marks each sweep's fronts (by seconds and by rays) and the front over all rows.
void mark_fronts(StudyResult& result) {
  const auto cost_quality = [](const StudyRow& r, bool rays) {
    return CostQuality{rays ? static_cast<double>(r.rays.total()) : r.seconds, r.diff.psnr};
  };
  std::vector<StudyRow*> all;
  for (StudyRow& r : result.rows) {
    if (r.sweep != "reference") all.push_back(&r);
  }
  for (bool by_rays : {false, true}) {
    std::vector<CostQuality> pts;
    for (const StudyRow* r : all) pts.push_back(cost_quality(*r, by_rays));
    const std::vector<bool> on = pareto_front(pts);
    for (size_t i = 0; i < all.size(); ++i) (by_rays ? all[i]->front_all_rays : all[i]->front_all) = on[i];
  }

  for (const KnobInfo& knob : result.knobs) {
    std::vector<StudyRow*> rows;
    for (StudyRow* r : all) {
      if (r->sweep == knob.name) rows.push_back(r);
    }
    for (bool by_rays : {false, true}) {
      std::vector<CostQuality> sweep_pts;
      for (const StudyRow* r : rows) sweep_pts.push_back(cost_quality(*r, by_rays));
      const std::vector<bool> on = pareto_front(sweep_pts);
      for (size_t i = 0; i < rows.size(); ++i) (by_rays ? rows[i]->front_rays : rows[i]->front) = on[i];
    }
  }
}

}  // namespace

// Option-level limits here; whether a knob's settings can be rendered is
// validate_settings()'s rule (render_settings.h), applied to every row the
// study would render, so the study accepts exactly what `render` accepts.
void validate(const StudyOptions& o) {
  // With the value found: "--min-time must be >= 0" alone left nan to guess.
  const auto found = [](double v) { return ", found " + format("%g", v); };
  require(o.size >= 1 && o.size <= 8192, "--size must be in 1..8192" + found(o.size));
  require(o.repeats >= 1 && o.repeats <= 100, "--repeats must be in 1..100" + found(o.repeats));
  require(o.min_timed_seconds >= 0 && std::isfinite(o.min_timed_seconds),
          "--min-time must be a finite number >= 0" + found(o.min_timed_seconds));
  require(o.threads >= 0 && o.threads <= kMaxThreads,
          "--threads must be in 0.." + std::to_string(kMaxThreads) + found(o.threads));
  require(o.cutoff_depth >= 1 && o.cutoff_depth <= kMaxDepth,
          "--cutoff-depth must be in 1.." + std::to_string(kMaxDepth) + found(o.cutoff_depth));
  // The rule's range, checked here so that the message names the option, not
  // the sweep row "cutoff -0.5" that would have rendered it.
  for (double c : o.cutoffs) require(c >= 0 && c <= 1, "--cutoffs values must be in [0, 1]" + found(c));
  const auto check = [](const RenderSettings& s, const std::string& what) {
    try {
      validate_settings(s);
    } catch (const InputError& e) {
      throw InputError("study: " + what + ": " + e.what());
    }
  };
  RenderSettings base;
  base.width = base.height = o.size;
  base.spp = o.base_spp;
  base.max_depth = o.base_depth;
  check(base, "--base-spp " + std::to_string(o.base_spp) + " / --base-depth " + std::to_string(o.base_depth));
  RenderSettings ref = base;
  ref.spp = o.reference_spp;
  ref.max_depth = o.reference_depth;
  check(ref, "--reference-spp " + std::to_string(o.reference_spp) + " / --reference-depth " +
                 std::to_string(o.reference_depth));
  // Every sweep left out: the study rendered its reference (minutes, at
  // 1024 spp) and wrote tables with no rows, exit code 0.
  require(!study_knobs(o).empty(),
          "nothing to sweep: --spp, --depths and --cutoffs are empty, the adaptive sweep too (--adaptive-spp or "
          "--contrast empty), --no-robust is given and there is no --preset");
  for (const Knob& knob : study_knobs(o)) {
    for (const KnobValue& v : knob.values) {
      RenderSettings s = base;
      v.apply(s);  // a preset throws here, naming itself, for an unknown key
      check(s, knob.info.name + " " + v.text);
    }
  }
  // The rule allows contrast 0 (uniform); in the adaptive sweep it would be a duplicate.
  for (double t : o.adaptive_thresholds) require(t > 0, "--contrast values must be > 0" + found(t));
}

RenderSettings study_base_settings(const Scene& scene, const StudyOptions& o) {
  RenderSettings s;
  s.width = o.size;
  // Keep the scene's aspect ratio (SPD scenes are square).
  const double aspect = scene.camera.width > 0
                            ? static_cast<double>(scene.camera.height) / scene.camera.width
                            : 1.0;
  s.height = std::max(1, static_cast<int>(std::lround(o.size * aspect)));
  s.spp = o.base_spp;
  s.max_depth = o.base_depth;
  s.threads = o.threads;
  s.seed = o.seed;
  return s;
}

StudyResult run_study(const Scene& scene, const StudyOptions& o, const StudyProgress& progress) {
  validate(o);
  StudyResult result;
  result.scene_name = o.scene_name;
  const RenderSettings base = study_base_settings(scene, o);
  result.base = base;
  result.width = base.width;
  result.height = base.height;
  const std::vector<Knob> knobs = study_knobs(o);
  size_t total = 1;
  for (const Knob& k : knobs) total += k.values.size();
  StudyRunner runner(scene, o, progress, total);

  const Rendered reference = reference_render(base, o, runner, result);
  runner.keep_image(reference.rgb, reference.row.settings, "reference.png", result);
  result.rows.push_back(reference.row);

  for (const Knob& knob : knobs) {
    result.knobs.push_back(knob.info);
    std::vector<const Rendered*> renders;
    for (const KnobValue& v : knob.values) {
      RenderSettings s = base;
      v.apply(s);
      const std::string label = knob.info.name + " " + v.text;
      const Rendered& r = runner.run(s, label, o.repeats, o.min_timed_seconds);
      runner.remember(knob.info.name, v.text, s);
      StudyRow row = r.row;
      row.reused = row.sweep != knob.info.name || row.value != v.text;
      row.sweep = knob.info.name;
      row.value = v.text;
      row.diff = compare_images(r.rgb, reference.rgb);
      runner.say("  " + label + format(": PSNR %.2f dB", row.diff.psnr) + format(", max error %.3f", row.diff.max_abs));
      if (knob.info.name == "spp" && !row.reused) {
        runner.keep_image(r.rgb, s, "spp-" + v.text + ".png", result);
      }
      result.rows.push_back(row);
      renders.push_back(&r);
    }
    // The knob's error alone: against its exact member, same sample positions.
    const size_t first = result.rows.size() - renders.size();
    for (size_t i = 0; i < knob.values.size(); ++i) {
      if (knob.values[i].text != knob.info.exact) continue;
      for (size_t j = 0; j < renders.size(); ++j) {
        result.rows[first + j].has_knob_diff = true;
        result.rows[first + j].knob_diff = compare_images(renders[j]->rgb, renders[i]->rgb);
      }
    }
  }
  mark_fronts(result);
  return result;
}

std::vector<const StudyRow*> rows_of(const StudyResult& result, const std::string& sweep) {
  std::vector<const StudyRow*> out;
  for (const StudyRow& row : result.rows) {
    if (row.sweep == sweep) out.push_back(&row);
  }
  return out;
}

const StudyRow* base_row(const StudyResult& result) {
  const std::string base = settings_key(result.base);
  for (const StudyRow& row : result.rows) {
    if (row.sweep != "reference" && settings_key(row.settings) == base) return &row;
  }
  return nullptr;
}

}  // namespace rayfarm
