// Row costs: how long each scanline of one image takes to render on one
// machine, the input of the farm replay. A profile is measured directly (each
// row rendered once by the tracer, timed) or read back from a farm job record
// (each task's render time shared evenly among its rows), and can be rescaled
// to another image height or to a known sequential time (the paper's Table 2).
#pragma once

#include <functional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "tracer/render_settings.h"
#include "tracer/scene.h"

namespace rayfarm {

// The longest time a replay takes from outside, in seconds (a row's cost, an
// init, a sequential time, a latency or a start-up stagger): about 32 years,
// far past any render, yet small enough that the simulator's clock, a double,
// still resolves a microsecond there. 1e300 s of init left 0 s of rendering
// in the report, and sums of larger values overflowed to inf.
inline constexpr double kMaxReplaySeconds = 1e9;

struct RowCosts {
  std::string scene;   // scene name, for reports
  std::string source;  // "tracer", "job record" or "synthetic", plus any rescaling
  int width = 0, spp = 0;
  size_t primitives = 0;     // 0 = unknown
  double init_s = 0;         // parse + BVH build on the measuring machine, 0 = unknown
  std::vector<double> rows;  // seconds per scanline, top row first

  int height() const { return static_cast<int>(rows.size()); }
  double total() const;                 // sum of all rows
  double sum(int y0, int y1) const;     // rows [y0, y1)
};

// Renders every row of `scene` with `settings` (threads as given; use 1 for a
// per-core profile) in `repeats` passes over the image and keeps each row's
// fastest time: on a shared machine a preemption only ever adds time, so the
// minimum is the robust estimate. Passes, not back-to-back repeats of a row:
// a 0.7 ms row timed three times in a row sits inside one 4-10 ms time slice
// of another process, which once gave isolated rows 10-20x their true cost.
// `progress(done, total)` after each row of each pass.
RowCosts measure_row_costs(const Scene& scene, const RenderSettings& settings, const std::string& name,
                           int repeats = 3, const std::function<void(int, int)>& progress = {});

// Per-row costs from a job record (broker/job_record.h): every done task's
// render_s (unthrottled) split evenly over its rows; a row rendered in pixel
// spans costs the sum of its spans. `name` is used in errors.
RowCosts row_costs_from_record(const nlohmann::json& record, const std::string& name);

// Reads a costs file written by row_costs_json, or a job record (told apart by
// its "tasks" key). InputError "path: ..." on anything malformed.
RowCosts load_row_costs(const std::string& path);

nlohmann::json row_costs_json(const RowCosts& costs);

// Area-preserving resampling to `height` rows: each new row covers an equal
// share of the old rows (fractions at the edges), so the total is unchanged.
RowCosts resample_rows(const RowCosts& costs, int height);

// Multiplies every row (and init_s) so that total() == `total_s`.
RowCosts scale_to_total(const RowCosts& costs, double total_s);

}  // namespace rayfarm
