// Validation of the replay against a real farm: measure the scene's row costs
// with the tracer (one thread per worker, each resting between rows as its
// throttled worker does, so the rows meet the farm's load), run a real broker
// with throttled `rayfarm worker` processes on this machine (throttle k = a
// machine k times slower), then replay the same
// configuration twice -- from the measured costs (a true prediction) and from
// the job record's own per-task render times (checks the dispatch model alone)
// -- and compare render times and per-worker row shares.
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "replay/row_costs.h"
#include "replay/simulator.h"

namespace rayfarm {

struct ValidationSpec {
  std::string scene_path;
  int width = 96, height = 96, spp = 64;
  std::vector<double> throttles{1, 2, 3};  // one worker per entry
  PolicyKind policy = PolicyKind::adaptive;
  bool declare_speed = false;  // workers announce weight = reference / throttle (else all the reference)
  int base_task_rows = 1;
  int credit = 2;
  int repeats = 3;           // row-cost measurements per row (the median counts)
  double latency_s = 2e-4;   // one-way broker <-> worker latency assumed by the replay
  std::string executable;    // the rayfarm binary the workers run
};

struct WorkerComparison {
  std::string name;
  double throttle = 1, weight = 0;
  int real_rows = 0, predicted_rows = 0, replayed_rows = 0;
  double real_share = 0, predicted_share = 0, replayed_share = 0;
  double real_busy_s = 0, predicted_busy_s = 0;
};

struct ValidationResult {
  RowCosts measured;        // tracer, before the farm run (threads = 1), as the farm's workers render
  RowCosts recorded;        // from the job record
  nlohmann::json record;
  SimResult predicted;      // from `measured`
  SimResult replayed;       // from `recorded`, with each worker's recorded init time
  double real_render_s = 0, real_total_s = 0;
  std::vector<WorkerComparison> workers;
  std::string markdown;     // a table of all of the above
};

// Throws InputError for a bad scene, std::runtime_error if the farm fails.
ValidationResult run_validation(const ValidationSpec& spec);

}  // namespace rayfarm
