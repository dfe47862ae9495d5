// The accuracy-vs-time study: renders one scene across the knobs that trade
// time for accuracy (samples per pixel, ray-tree depth, adaptive supersampling,
// ray-tree pruning by weight, Embree's robust traversal) and measures each render against a converged
// reference: wall time, rays traced, RMSE and PSNR. The numbers come from here;
// study_report.h turns them into study.csv / study.md and scripts/plot_study.py
// into plots.
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
  int size = 128;            // image width; height follows the scene's aspect
  int reference_spp = 1024;  // must be a square, like every spp below
  int reference_depth = 5;   // SPD convention; the spp, adaptive and robust rows use it too
  std::vector<int> spp_list{1, 4, 16, 64, 256};
  std::vector<int> depth_list{1, 2, 3, 4, 5, 6, 7, 8};
  int depth_spp = 16;  // spp of the depth sweep (compared with its deepest row)
  std::vector<int> adaptive_spp{16, 64};
  std::vector<double> adaptive_thresholds{0.4, 0.2, 0.1, 0.05, 0.025};
  // Ray-tree pruning (render_settings.h): each cutoff at cutoff_spp.
  std::vector<double> cutoffs{0.01, 0.001, 0.0001};
  int cutoff_spp = 16;
  int robust_spp = 16;
  int threads = 0;  // 0 = all hardware threads
  // Each timed render (not the reference) runs this often; the minimum time is
  // kept, as the peers' timings on this shared kind of machine are.
  int repeats = 2;
  uint64_t seed = 0;
  bool write_images = true;  // reference.png and spp-N.png into out_dir
};

// One render of the study.
struct StudyRow {
  std::string sweep;     // "reference", "spp", "depth", "adaptive", "cutoff" or "robust"
  std::string baseline;  // what `diff` compares against: "reference", "depth-8", "none"
  RenderSettings settings;
  double seconds = 0;        // wall time of the render (minimum over repeats), BVH build excluded
  double build_seconds = 0;  // BVH build of this render's Renderer
  RayStats rays;
  ImageDiff diff;  // meaningless when baseline == "none"
  size_t non_finite = 0;  // NaN/Inf values in the render (0 for a healthy tracer)
};

struct StudyResult {
  std::string scene_name;
  int width = 0, height = 0;
  std::vector<StudyRow> rows;  // reference first, then the sweeps in the order above
  ImageDiff robust_on_vs_off;  // the two robust-sweep images against each other
  std::vector<std::string> images;  // file names written into out_dir
};

// Progress lines ("study: [3/26] spp 16: 0.42 s, PSNR 31.2 dB"); may be empty.
using StudyProgress = std::function<void(const std::string&)>;

// Checks the options (squares for every spp, depths >= 1, sizes > 0) and throws
// InputError naming the bad option.
void validate(const StudyOptions& options);

// Runs every sweep on `scene`. Writes nothing but the images (write_images).
StudyResult run_study(const Scene& scene, const StudyOptions& options,
                      const StudyProgress& progress = {});

// The rows of one sweep, in run order.
std::vector<const StudyRow*> rows_of(const StudyResult& result, const std::string& sweep);

}  // namespace rayfarm
