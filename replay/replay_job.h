// One `rayfarm replay`: get a row cost profile (a costs file, a job record, or
// measured with the tracer), shape it (resample, scale to a known sequential
// time), expand a lab, simulate the whole lab and optionally the speedup sweeps,
// and write the results (costs.json, replay.md, sweep.csv, machines.csv).
#pragma once

#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "replay/lab.h"
#include "replay/simulator.h"
#include "replay/sweep.h"

namespace rayfarm {

struct ReplayJob {
  std::string costs_path;  // costs file or job record; or:
  std::string scene_path;  // measure each row with the tracer
  std::optional<int> width, height;
  int spp = 1;
  int threads = 1;         // measurement threads: 1 = a per-core profile
  int repeats = 3;         // renders per row; the fastest counts
  std::string paper;       // "tetra", ...: rows 512, Table 2 sequential time, paper init and start-up
  std::optional<int> rows;             // resample to this many rows
  std::optional<double> sequential_s;  // scale the profile to this total (minus init)
  std::optional<double> init_s;        // init on a speed-1 machine; default: the profile's
  std::optional<double> stagger_s;     // machine i starts i * stagger_s late; default 0, or the paper's with `paper`
  std::string lab_path;
  SpeedFrom speed_from = SpeedFrom::weight;
  std::optional<int> credit;  // tasks in flight for every machine; default: each worker config's
  SimOptions sim;
  bool sweep = false;
  std::string out_dir;     // "" = print only
};

struct ReplayOutput {
  std::string scene;
  RowCosts costs;
  Lab lab;
  SimOptions options;  // as simulated
  SimResult whole;
  std::vector<SweepPoint> points;
  double init_bound = 0;
  std::string markdown;
  std::vector<std::string> files;  // written into out_dir
};

using ReplayProgress = std::function<void(const std::string& what, int done, int total)>;

// Throws InputError for bad input (missing files, unknown lab keys, bad sizes).
ReplayOutput run_replay(const ReplayJob& job, const ReplayProgress& progress = {});

}  // namespace rayfarm
