// Calibration tests: the measured weight follows the documented anchor (the
// paper's Table 2 Sphere time on a Sun SSC = weight 21), and the written
// worker config loads back with that weight. No timing is asserted.
#include <doctest/doctest.h>

#include <unistd.h>

#include <filesystem>

#include "tests/run_command.h"
#include "tests/test_paths.h"
#include "tracer/text_file.h"
#include "worker/calibration.h"
#include "worker/worker_config.h"

using namespace rayfarm;

TEST_CASE("calibrate: weight = 21 x the paper's SSC time for the image / our time, the config loads back") {
  CalibrationSpec spec;
  spec.width = spec.height = 16;
  spec.spp = 1;
  spec.threads = 1;
  spec.repeats = 1;
  const Calibration c = calibrate(spec);
  CHECK(c.render_s > 0);
  CHECK(c.ssc_s == doctest::Approx(27612.79 * 16 * 16 / (512.0 * 512.0 * 16)));
  CHECK(c.weight == doctest::Approx(21.0 * c.ssc_s / c.render_s));
  // A 16x16 image at one sample is over in well under the steady minimum.
  CHECK(c.warning.find("too short for a steady weight") != std::string::npos);
  const std::string path = (std::filesystem::temp_directory_path() /
                            ("rayfarm-calibration-" + std::to_string(getpid()) + ".json")).string();
  write_json_file(path, calibrated_worker_config(c));
  const WorkerConfig w = load_worker_config(path);
  CHECK(w.weight == doctest::Approx(c.weight));
  CHECK(w.threads == 1);
  CHECK(w.description.find("Table 2") != std::string::npos);
  std::filesystem::remove(path);
  // The command line writes the same kind of file.
  const std::string cli = path + ".cli.json";
  const test::CommandResult r =
      test::run_command(test::rayfarm_exe() + " calibrate -o " + cli + " --size 16 --spp 1 --repeats 1 --threads 1");
  REQUIRE(r.exit_code == 0);
  CHECK(r.output.find("rayfarm: warning: the fastest render took") != std::string::npos);
  CHECK(load_worker_config(cli).weight > 0);
  std::filesystem::remove(cli);
}

TEST_CASE("calibrate: an output that cannot be written fails with the reason, before the renders") {
  const test::CommandResult r =
      test::run_command(test::rayfarm_exe() + " calibrate -o /nonexistent-dir/machine.json --size 16 --spp 1");
  CHECK(r.exit_code != 0);
  CHECK(r.output.find("/nonexistent-dir/machine.json: cannot write (no directory /nonexistent-dir)") !=
        std::string::npos);
}
