// The accuracy-vs-time study: renders one scene across the knobs that trade
// time for accuracy and measures each render against a converged reference:
// wall time, rays traced, PSNR and maximum error. Every knob is swept on its
// own around the SPD's own settings (16 spp, depth 5), and each sweep gets its
// Pareto front (pareto.h). The numbers come from here; study_report.h writes
// them as study.csv / study.md and scripts/plot_study.py draws the plots.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "study/image_metrics.h"
#include "tracer/ray_stats.h"
#include "tracer/render_settings.h"
#include "tracer/scene.h"

namespace rayfarm {

struct StudyOptions {
  std::string scene_name = "scene";  // shown in the CSV and the report
  std::string out_dir = "out/study";
  std::string reference_cache;  // directory of cached references; empty = always render it
  std::string scene_file;       // a cached reference older than this file is stale
  int size = 128;               // image width; height follows the scene's aspect
  int reference_spp = 1024;     // must be a square, like every spp below
  // Deeper than the SPD's 5, so that the depth sweep (and the SPD's depth
  // itself) shows its truncation error against the reference.
  int reference_depth = 10;
  // The base every sweep varies one knob of: the SPD's own settings.
  int base_spp = 16;
  int base_depth = 5;
  std::vector<int> spp_list{1, 4, 16, 64};
  std::vector<int> depth_list{1, 2, 3, 4, 5, 6, 8, 10};
  std::vector<int> adaptive_spp{16, 64};
  std::vector<double> adaptive_thresholds{0.2, 0.1, 0.05, 0.025};
  // Ray-tree pruning by path weight (render_settings.h); 0 is the full tree.
  // Swept at cutoff_depth: pruning is an alternative to a low depth limit, and
  // at the SPD's depth 5 the sphereflake's weights (0.5^4) never fall below 0.1.
  std::vector<double> cutoffs{0, 0.01, 0.03, 0.1, 0.3};
  int cutoff_depth = 10;
  bool robust = true;  // sweep Embree's robust traversal off / on
  // Settings that change several knobs at once, e.g. "spp=64,depth=8": the
  // candidates for a recommendation, measured like every other row.
  std::vector<std::string> presets;
  int threads = 0;     // 0 = all hardware threads
  // Each timed render (not the reference) runs at least `repeats` times, and
  // again (up to 10 runs) while its runs add up to less than `min_timed_seconds`;
  // the minimum time is kept, as the peers' timings on this shared kind of
  // machine are. Cheap renders, the noisiest, so get the most runs.
  int repeats = 2;
  double min_timed_seconds = 1.0;
  uint64_t seed = 0;
  bool write_images = true;  // reference.png and spp-N.png into out_dir
};

// One knob's sweep, as the report describes it.
struct KnobInfo {
  std::string name;    // the `sweep` of its rows: "spp", "depth", "adaptive", "cutoff", "robust"
  std::string column;  // heading of the value column in tables
  std::string what;    // one sentence: what the knob does and what stays fixed
  std::string exact;   // value that is exact for this knob at the same samples; "" = none
};

// One render of the study.
struct StudyRow {
  std::string sweep;  // "reference" or a KnobInfo::name
  std::string value;  // the knob's value as text ("16", "64/0.05", "on")
  RenderSettings settings;
  double seconds = 0;        // wall time of the render (minimum over repeats), BVH build excluded
  double build_seconds = 0;  // BVH build of this render's Renderer
  int runs = 0;              // timed runs behind `seconds`
  RayStats rays;
  ImageDiff diff;  // against the reference (meaningless for the reference row)
  // Against the sweep's exact member at the same sample positions: the error
  // of this knob alone (depth: against the deepest; cutoff: against 0, the
  // full tree; robust: against "on").
  bool has_knob_diff = false;
  ImageDiff knob_diff;
  uint64_t non_finite = 0;  // NaN/Inf samples the tracer returned (raw count, RayStats)
  bool reused = false;    // same settings as an earlier row: its render, not a new one
  bool front = false;       // on its sweep's Pareto front, cost = seconds
  bool front_rays = false;  // on its sweep's Pareto front, cost = rays traced
  bool front_all = false;       // on the front over every knob's rows, cost = seconds
  bool front_all_rays = false;  // on the front over every knob's rows, cost = rays traced
};

struct StudyResult {
  std::string scene_name;
  int width = 0, height = 0;
  RenderSettings base;            // the settings every sweep varies one knob of
  bool reference_cached = false;  // the reference came from the cache
  std::vector<KnobInfo> knobs;    // in sweep order
  std::vector<StudyRow> rows;     // reference first, then the sweeps in knob order
  std::vector<std::string> images;  // file names written into out_dir
};

// Progress lines ("study: balls [3/26, 41 s] spp 16: 0.42 s, PSNR 31.2 dB"); may be empty.
using StudyProgress = std::function<void(const std::string&)>;

// Checks the options (squares for every spp, depths >= 1, sizes > 0) and throws
// InputError naming the bad option.
void validate(const StudyOptions& options);

// The base settings of a study (size, SPD spp and depth, threads, seed).
RenderSettings study_base_settings(const Scene& scene, const StudyOptions& options);

// Runs the reference and every sweep on `scene`. Writes nothing but the images
// (write_images) and the reference cache entry (reference_cache); a corrupt
// entry is reported through `progress` and rewritten.
StudyResult run_study(const Scene& scene, const StudyOptions& options,
                      const StudyProgress& progress = {});

// The rows of one sweep, in run order.
std::vector<const StudyRow*> rows_of(const StudyResult& result, const std::string& sweep);

// The first row rendered with the base settings (the SPD's own), or nullptr.
const StudyRow* base_row(const StudyResult& result);

}  // namespace rayfarm
