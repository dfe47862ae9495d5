// Calibration: measures this machine's render speed and expresses it as a
// worker weight on the SPECfp92 scale of configs/workers (Sun SSC = 21.0).
// The anchor is the paper's Table 2: a Sun SSC running Rayshade rendered the
// Sphere scene (SPD balls, size 4) at 512x512, 16 spp in 27612.79 s. This
// machine renders the same scene (smaller, the time scaled by pixels x spp)
// with rayfarm's tracer, so weight = 21 x SSC time / our time: how many of the
// paper's SSCs the machine is worth on that work, software included.
#pragma once

#include <string>

#include <nlohmann/json.hpp>

namespace rayfarm {

struct CalibrationSpec {
  int width = 128, height = 128, spp = 16;
  int threads = 0;  // the threads the worker will render with; 0 = all cores
  int repeats = 3;  // the fastest render counts (preemption only adds time)
};

struct Calibration {
  double render_s = 0;      // fastest render of the reference image here
  double ssc_s = 0;         // the same image on the paper's SSC (Table 2, scaled)
  double weight = 0;        // 21 x ssc_s / render_s
  int threads = 0;
  std::string description;  // for the worker config
  std::string warning;      // why the weight may not be steady; empty if it is
};

// Throws InputError for settings the tracer refuses.
Calibration calibrate(const CalibrationSpec& spec);

// A worker config (configs/workers/*.json format) with the measured weight.
nlohmann::json calibrated_worker_config(const Calibration& c);

}  // namespace rayfarm
