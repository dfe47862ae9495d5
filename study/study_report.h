// Writing up an accuracy study: study.csv (one row per render, every number the
// plots use, Pareto fronts included) and study.md (the tables a reader wants:
// the SPD setting's place, the front over all knobs, one table per knob), plus
// the equal-time and equal-quality comparisons of adaptive against uniform
// supersampling, which are interpolated from the uniform spp sweep.
#pragma once

#include <string>
#include <vector>

#include "study/pareto.h"
#include "study/plot_script.h"
#include "study/quality_study.h"

namespace rayfarm {

// Everything a study leaves in its output directory.
struct StudyFiles {
  std::string csv;       // <out_dir>/study.csv
  std::string markdown;  // <out_dir>/study.md
  PlotOutcome plots;     // PNGs in <out_dir>, or why there are none
};

// Creates options.out_dir, writes study.csv, runs the plot script on it (when
// `plots`; `plot_script` empty = search, see find_plot_script) and writes
// study.md naming the plots.
StudyFiles write_study(const StudyResult& result, const StudyOptions& options, bool plots,
                       const std::string& plot_script = "");

// The CSV header's column names, in order.
const std::vector<std::string>& study_csv_columns();

// Writes the CSV / Markdown; throws std::runtime_error naming the path on failure.
void write_study_csv(const StudyResult& result, const std::string& path);
void write_study_markdown(const StudyResult& result, const StudyOptions& options,
                          const std::string& path, const std::vector<std::string>& plots,
                          const std::string& plot_note);

// PSNR uniform sampling reaches at `cost`, interpolating PSNR linearly in
// log(cost) between the sweep's points; NaN outside the sweep's range.
double psnr_at_cost(std::vector<CostQuality> uniform, double cost);

// Cost uniform sampling needs to reach `psnr` (first crossing along increasing
// cost, linear in log cost); NaN when the sweep never reaches it.
double cost_for_psnr(std::vector<CostQuality> uniform, double psnr);

enum class Cost { kSeconds, kRays };

// The uniform spp sweep of a result as cost/PSNR points (cost: seconds, or
// rays traced, which do not depend on how busy the machine was).
std::vector<CostQuality> uniform_curve(const StudyResult& result, Cost cost);

}  // namespace rayfarm
