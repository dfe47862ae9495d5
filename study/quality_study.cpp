// The accuracy-vs-time study: one Renderer per knob setting, timed, compared
// with a converged reference (or, for the depth sweep, with its deepest row).
#include "study/quality_study.h"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>
#include <utility>

#include "tracer/error.h"
#include "tracer/image_io.h"
#include "tracer/renderer.h"
#include "tracer/sampler.h"

namespace rayfarm {

namespace {

struct Rendered {
  std::vector<float> rgb;
  StudyRow row;
};

bool is_square(int n) { return n >= 1 && grid_size(n) * grid_size(n) == n; }

void require(bool ok, const std::string& what) {
  if (!ok) throw InputError("study: " + what);
}

std::string format(const char* fmt, double value) {
  char buf[128];
  std::snprintf(buf, sizeof buf, fmt, value);
  return buf;
}

// Settings shared by every render of the study; the sweeps change one knob each.
RenderSettings base_settings(const Scene& scene, const StudyOptions& o) {
  RenderSettings s;
  s.width = o.size;
  // Keep the scene's aspect ratio (SPD scenes are square).
  const double aspect = scene.camera.width > 0
                            ? static_cast<double>(scene.camera.height) / scene.camera.width
                            : 1.0;
  s.height = std::max(1, static_cast<int>(std::lround(o.size * aspect)));
  s.spp = 1;
  s.max_depth = o.reference_depth;
  s.threads = o.threads;
  s.seed = o.seed;
  return s;
}

// Renders `repeats` times (one Renderer, so one BVH build) and keeps the
// fastest time; the image and ray counts are those of the first run.
Rendered render(const Scene& scene, const RenderSettings& settings, std::string sweep, int repeats) {
  Rendered out;
  out.row.sweep = std::move(sweep);
  out.row.settings = settings;
  const Renderer renderer(scene, settings);
  out.row.build_seconds = renderer.build_seconds();
  std::vector<float> again;
  for (int i = 0; i < std::max(1, repeats); ++i) {
    RayStats rays;
    const auto t0 = std::chrono::steady_clock::now();
    renderer.render_rows(0, settings.height, i == 0 ? out.rgb : again, &rays);
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    if (i == 0) {
      out.row.rays = rays;
      out.row.seconds = seconds;
    } else {
      out.row.seconds = std::min(out.row.seconds, seconds);
    }
  }
  out.row.non_finite = count_non_finite(out.rgb);
  return out;
}

// Runs the renders and reports progress; owns the numbering "[i/n]".
class StudyRunner {
 public:
  StudyRunner(const Scene& scene, const StudyOptions& options, const StudyProgress& progress)
      : scene_(scene), options_(options), progress_(progress) {
    total_ = 1 + options.spp_list.size() + options.depth_list.size() +
             options.adaptive_spp.size() * options.adaptive_thresholds.size() + options.cutoffs.size() + 2;
  }

  Rendered run(const RenderSettings& settings, const std::string& sweep, const std::string& label,
               int repeats) {
    ++done_;
    say("[" + std::to_string(done_) + "/" + std::to_string(total_) + "] " + label + " ...");
    Rendered r = render(scene_, settings, sweep, repeats);
    say("  " + label + ": " + format("%.3f s, ", r.row.seconds) + std::to_string(r.row.rays.total()) + " rays");
    if (r.row.non_finite > 0) {
      say("  warning: " + std::to_string(r.row.non_finite) + " non-finite values in " + label);
    }
    return r;
  }

  // Writes the image as out_dir/name when images are wanted.
  void keep_image(const Rendered& r, const std::string& name, StudyResult& result) const {
    if (!options_.write_images) return;
    std::filesystem::create_directories(options_.out_dir);
    write_image((std::filesystem::path(options_.out_dir) / name).string(), r.row.settings.width,
                r.row.settings.height, r.rgb);
    result.images.push_back(name);
  }

  void compare(Rendered& r, const std::vector<float>& against, const std::string& baseline,
               const std::string& label) {
    r.row.baseline = baseline;
    r.row.diff = compare_images(r.rgb, against);
    say("  " + label + ": " + format("PSNR %.2f dB vs ", r.row.diff.psnr) + baseline);
  }

  void say(const std::string& line) const {
    if (progress_) progress_("study: " + line);
  }

 private:
  const Scene& scene_;
  const StudyOptions& options_;
  const StudyProgress& progress_;
  size_t total_ = 0;
  size_t done_ = 0;
};

std::string spp_label(const char* what, int value) { return std::string(what) + " " + std::to_string(value); }

}  // namespace

void validate(const StudyOptions& o) {
  require(o.size >= 1 && o.size <= 8192, "--size must be in 1..8192");
  require(is_square(o.reference_spp), "--reference-spp must be a square (k*k), got " +
                                          std::to_string(o.reference_spp));
  require(o.reference_depth >= 1, "reference depth must be >= 1");
  require(o.repeats >= 1 && o.repeats <= 100, "--repeats must be in 1..100");
  require(!o.spp_list.empty(), "the spp list is empty");
  for (int spp : o.spp_list) require(is_square(spp), "spp " + std::to_string(spp) + " is not a square");
  for (int spp : o.adaptive_spp) {
    require(is_square(spp), "adaptive spp " + std::to_string(spp) + " is not a square");
  }
  require(is_square(o.depth_spp), "depth-sweep spp must be a square");
  require(is_square(o.robust_spp), "robust-mode spp must be a square");
  require(is_square(o.cutoff_spp), "cutoff-sweep spp must be a square");
  for (double c : o.cutoffs) require(c > 0 && c <= 1, "cutoffs must be in (0, 1]");
  require(!o.depth_list.empty(), "the depth list is empty");
  for (int d : o.depth_list) require(d >= 1, "depth " + std::to_string(d) + " is below 1");
  for (double t : o.adaptive_thresholds) {
    require(t > 0 && std::isfinite(t), "adaptive thresholds must be > 0");
  }
}

StudyResult run_study(const Scene& scene, const StudyOptions& o, const StudyProgress& progress) {
  validate(o);
  StudyResult result;
  result.scene_name = o.scene_name;
  const RenderSettings base = base_settings(scene, o);
  result.width = base.width;
  result.height = base.height;
  StudyRunner runner(scene, o, progress);

  // The converged reference: many jittered samples at the SPD depth, from an
  // independent seed so that no sweep shares its sample positions.
  RenderSettings ref_settings = base;
  ref_settings.spp = o.reference_spp;
  ref_settings.seed = o.seed + 1;
  Rendered reference = runner.run(ref_settings, "reference", spp_label("reference spp", o.reference_spp), 1);
  reference.row.baseline = "none";
  runner.keep_image(reference, "reference.png", result);
  result.rows.push_back(reference.row);

  for (int spp : o.spp_list) {
    RenderSettings s = base;
    s.spp = spp;
    Rendered r = runner.run(s, "spp", spp_label("spp", spp), o.repeats);
    runner.compare(r, reference.rgb, "reference", spp_label("spp", spp));
    runner.keep_image(r, "spp-" + std::to_string(spp) + ".png", result);
    result.rows.push_back(r.row);
  }

  // Depth: same spp and seed for every depth, so the sample positions agree and
  // the difference to the deepest render is the truncation of the ray tree alone.
  std::vector<Rendered> by_depth;
  for (int depth : o.depth_list) {
    RenderSettings s = base;
    s.spp = o.depth_spp;
    s.max_depth = depth;
    by_depth.push_back(runner.run(s, "depth", spp_label("depth", depth), o.repeats));
  }
  size_t deepest = 0;
  for (size_t i = 0; i < by_depth.size(); ++i) {
    if (o.depth_list[i] > o.depth_list[deepest]) deepest = i;
  }
  const std::string depth_baseline = "depth-" + std::to_string(o.depth_list[deepest]);
  for (size_t i = 0; i < by_depth.size(); ++i) {
    runner.compare(by_depth[i], by_depth[deepest].rgb, depth_baseline,
                   spp_label("depth", o.depth_list[i]));
    result.rows.push_back(by_depth[i].row);
  }

  for (int spp : o.adaptive_spp) {
    for (double t : o.adaptive_thresholds) {
      RenderSettings s = base;
      s.spp = spp;
      s.adaptive_contrast = t;
      const std::string label = spp_label("adaptive spp", spp) + format(" contrast %g", t);
      Rendered r = runner.run(s, "adaptive", label, o.repeats);
      runner.compare(r, reference.rgb, "reference", label);
      result.rows.push_back(r.row);
    }
  }

  for (double cutoff : o.cutoffs) {
    RenderSettings s = base;
    s.spp = o.cutoff_spp;
    s.cutoff = cutoff;
    const std::string label = spp_label("cutoff spp", o.cutoff_spp) + format(" cutoff %g", cutoff);
    Rendered r = runner.run(s, "cutoff", label, o.repeats);
    runner.compare(r, reference.rgb, "reference", label);
    result.rows.push_back(r.row);
  }

  std::vector<float> robust_off;
  for (bool robust : {false, true}) {
    RenderSettings s = base;
    s.spp = o.robust_spp;
    s.robust_bvh = robust;
    const std::string label = std::string("robust ") + (robust ? "on" : "off");
    Rendered r = runner.run(s, "robust", label, o.repeats);
    runner.compare(r, reference.rgb, "reference", label);
    result.rows.push_back(r.row);
    if (robust) {
      result.robust_on_vs_off = compare_images(r.rgb, robust_off);
    } else {
      robust_off = std::move(r.rgb);
    }
  }
  return result;
}

std::vector<const StudyRow*> rows_of(const StudyResult& result, const std::string& sweep) {
  std::vector<const StudyRow*> out;
  for (const StudyRow& row : result.rows) {
    if (row.sweep == sweep) out.push_back(&row);
  }
  return out;
}

}  // namespace rayfarm
