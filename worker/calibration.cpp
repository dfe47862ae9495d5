// Worker calibration; see calibration.h.
#include "worker/calibration.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <sstream>
#include <thread>

#include "spd/generators.h"
#include "tracer/error.h"
#include "tracer/nff_reader.h"
#include "tracer/renderer.h"

namespace rayfarm {
namespace {

constexpr double kSscWeight = 21.0;          // Table 1: Sun SPARCclassic, SPECfp92
constexpr double kSscSphereS = 27612.79;     // Table 2: Sphere, 512 x 512, 16 spp, one SSC
constexpr double kSscSphereSamples = 512.0 * 512.0 * 16.0;
constexpr int kSphereSize = 4;               // SPD balls at the paper's 7382 primitives
// Below this a render's time is mostly the clock's grain, the threads' start
// and cold caches: at 8x8 the weight came out 1.6e5 to 4.3e5 from run to run,
// against 1.9e5 to 2.0e5 at the default 128x128 (0.18-0.19 s).
constexpr double kSteadyRenderS = 0.05;

}  // namespace

Calibration calibrate(const CalibrationSpec& spec) {
  std::ostringstream nff;
  spd::generate("balls", kSphereSize, nff);
  const Scene scene = parse_nff(nff.str(), "balls (calibration)");
  RenderSettings s;
  s.width = spec.width;
  s.height = spec.height;
  s.spp = spec.spp;
  s.threads = spec.threads;
  const Renderer renderer(scene, s);
  std::vector<float> rgb;
  Calibration c;
  c.render_s = 1e300;
  for (int i = 0; i < std::max(1, spec.repeats); ++i) {
    const auto t0 = std::chrono::steady_clock::now();
    renderer.render_rows(0, s.height, rgb);
    c.render_s = std::min(c.render_s, std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  }
  c.ssc_s = kSscSphereS * (double(s.width) * s.height * s.spp) / kSscSphereSamples;
  c.weight = kSscWeight * c.ssc_s / c.render_s;
  c.threads = spec.threads;
  const unsigned cores = spec.threads > 0 ? static_cast<unsigned>(spec.threads) : std::thread::hardware_concurrency();
  char buf[256];
  std::snprintf(buf, sizeof buf,
                "Calibrated: SPD balls %dx%d, %d spp on %u thread(s) in %.3f s; the paper's Sun SSC (SPECfp92 21) "
                "took %.1f s for it (Table 2, scaled): weight %.4g",
                s.width, s.height, s.spp, cores, c.render_s, c.ssc_s, c.weight);
  c.description = buf;
  if (c.render_s < kSteadyRenderS) {
    std::snprintf(buf, sizeof buf, "the fastest render took %.2f ms, too short for a steady weight (%.0f ms or more); "
                  "use a larger --size or --spp", c.render_s * 1000, kSteadyRenderS * 1000);
    c.warning = buf;
  }
  return c;
}

nlohmann::json calibrated_worker_config(const Calibration& c) {
  return {{"description", c.description},
          {"weight", c.weight},
          {"threads", c.threads},
          {"credit", 2},
          {"heartbeat", {{"interval_ms", 1000}, {"liveness", 3}}},
          {"reconnect", {{"initial_ms", 1000}, {"max_ms", 32000}}}};
}

}  // namespace rayfarm
