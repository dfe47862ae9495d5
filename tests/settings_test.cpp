// The one render-settings rule (tracer/render_settings.h) and its users: the
// in-process job, the protocol decoder, the broker and `rayfarm broker` all
// refuse exactly what validate_settings refuses, before any work is done.
#include <doctest/doctest.h>

#include <nlohmann/json.hpp>

#include "broker/broker.h"
#include "protocol/codec.h"
#include "tests/run_command.h"
#include "tests/test_files.h"
#include "tests/test_paths.h"
#include "tracer/error.h"
#include "tracer/render_settings.h"

using namespace rayfarm;

namespace {

RenderSettings with(void (*change)(RenderSettings&)) {
  RenderSettings s;
  change(s);
  return s;
}

// A `job` message whose settings JSON was edited after encoding, so values
// the encoder would never produce reach the decoder.
protocol::Frames job_frames(const RenderSettings& s) {
  protocol::JobSpec job;
  job.job = 1;
  job.scene_text = test::tiny_scene();
  job.scene_hash = protocol::fnv1a64(job.scene_text);
  job.scene_name = "tiny.nff";
  job.settings = s;
  return protocol::encode(protocol::Message{job});
}

std::string rejection(const protocol::Frames& frames) {
  try {
    protocol::decode(frames);
  } catch (const protocol::ProtocolError& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST_CASE("settings: validate_settings names the setting it refuses") {
  CHECK_NOTHROW(validate_settings(RenderSettings{}));
  CHECK_NOTHROW(validate_settings(with([](RenderSettings& s) { s.spp = 65536; })));
  struct Case {
    RenderSettings settings;
    const char* message;
  } cases[] = {
      {with([](RenderSettings& s) { s.spp = 10; }), "spp must be a perfect square k*k (1, 4, 9, 16, 25, ...), found 10"},
      {with([](RenderSettings& s) { s.spp = 0; }), "spp must be between 1 and 65536, found 0"},
      {with([](RenderSettings& s) { s.width = 0; }), "width must be between 1 and 65536, found 0"},
      {with([](RenderSettings& s) { s.height = 65537; }), "height must be between 1 and 65536, found 65537"},
      {with([](RenderSettings& s) { s.max_depth = 65; }), "depth must be between 1 and 64, found 65"},
      {with([](RenderSettings& s) { s.threads = -1; }), "threads must be between 0 and 4096, found -1"},
      {with([](RenderSettings& s) { s.adaptive_contrast = -1; }), "adaptive contrast must be a finite number"},
      {with([](RenderSettings& s) { s.adaptive_contrast = 1.0 / 0.0; }), "adaptive contrast must be a finite number"},
      // Finite, but past the bound: the message says which bound, in few digits.
      {with([](RenderSettings& s) { s.adaptive_contrast = 1e308; }),
       "adaptive contrast must be a finite number >= 0 and <= 1e+30, found 1e+308"},
      // In few digits too: std::to_string wrote -0.500000, and 1e300 in 301 digits.
      {with([](RenderSettings& s) { s.cutoff = -0.5; }), "cutoff must be between 0 and 1, found -0.5"},
      {with([](RenderSettings& s) { s.cutoff = 1e300; }), "cutoff must be between 0 and 1, found 1e+300"},
  };
  for (const Case& c : cases) {
    CAPTURE(c.message);
    CHECK_THROWS_WITH_AS(validate_settings(c.settings), doctest::Contains(c.message), InputError);
  }
}

TEST_CASE("settings: the decoder applies the same rule to a job's settings") {
  CHECK(rejection(job_frames(RenderSettings{})).empty());
  // spp 10 is in the old wire range [1, 65536] but no worker can render it.
  CHECK(rejection(job_frames(with([](RenderSettings& s) { s.spp = 10; }))) ==
        "settings.spp must be a perfect square k*k (1, 4, 9, 16, 25, ...), found 10");
  CHECK(rejection(job_frames(with([](RenderSettings& s) { s.width = 70000; }))).find("settings.width") == 0);
}

TEST_CASE("settings: the broker refuses a job no worker could render") {
  BrokerConfig cfg;
  cfg.bind = cfg.announce_bind = "tcp://127.0.0.1:*";
  cfg.min_workers = 0;
  cfg.progress = false;
  Broker broker(cfg, [](const std::string&) {});
  FarmJob job{test::tiny_scene(), "tiny.nff", with([](RenderSettings& s) { s.spp = 10; })};
  CHECK_THROWS_WITH_AS(broker.run(job), doctest::Contains("spp must be a perfect square"), InputError);
}

TEST_CASE("settings: `rayfarm broker` prepares its job like `render` and fails before binding") {
  const auto dir = test::scratch_dir("settings");
  const std::string scene = test::write_file(dir / "tiny.nff", test::tiny_scene());
  const std::string loopback = " --bind tcp://127.0.0.1:* --announce tcp://127.0.0.1:* --no-progress";
  struct Case {
    std::string args;
    std::string message;
  } cases[] = {
      // Each of these used to bind and wait for workers (forever, or until the
      // whole job was rendered) before failing.
      {scene + " -o " + (dir / "x.png").string() + " --spp 10", "--spp: expected a perfect square"},
      {scene + " -o " + (dir / "x.xyz").string(), "x.xyz"},
      {scene + " -o " + (dir / "nodir" / "x.png").string(), "cannot write"},
      {scene + " -o /proc/x.png", "/proc/x.png: cannot write"},
      {scene + " -o " + (dir / "x.png").string() + " --stats " + (dir / "nodir" / "s.json").string(), "cannot write"},
      {scene + " -o " + (dir / "x.png").string() + " --record /proc/r.json", "/proc/r.json: cannot write"},
      {(dir / "missing.nff").string() + " -o " + (dir / "x.png").string(), "missing.nff: cannot open"},
  };
  for (const Case& c : cases) {
    CAPTURE(c.args);
    // `timeout` turns the old behaviour (waiting for workers) into exit 124.
    const test::CommandResult r =
        test::run_command("timeout 20 " + test::rayfarm_exe() + " broker " + c.args + loopback);
    CHECK(r.exit_code == 1);
    CHECK(r.output.find(c.message) != std::string::npos);
    CHECK(r.output.find("workers connect to") == std::string::npos);
  }
  std::filesystem::remove_all(dir);
}

TEST_CASE("settings: `render`, `broker` and `submit` take the same image options and refuse the same values") {
  const auto dir = test::scratch_dir("image-options");
  const std::string scene = test::write_file(dir / "tiny.nff", test::tiny_scene());
  const std::string out = " -o " + (dir / "x.png").string();
  const std::string commands[] = {
      "render " + scene + out,
      "broker " + scene + out + " --bind tcp://127.0.0.1:* --announce tcp://127.0.0.1:* --no-progress",
      "submit " + scene + " --broker http://127.0.0.1:1",  // refused before it connects
  };
  struct Case {
    std::string args;
    std::string message;
  } cases[] = {
      // A given 0 is refused, not taken for "the scene's resolution" (submit took it so).
      // Named by the option.
      {" --width 0", "--width: expected a value in [1, 65536], found 0"},
      {" --height 0", "--height: expected a value in [1, 65536], found 0"},
      // Every command knows --adaptive and --cutoff (broker and submit lacked
      // them): the --spp square check, not an unknown option, refuses these.
      {" --adaptive 0.1 --cutoff 0.02 --spp 10", "--spp: expected a perfect square"},
      {" --adaptive --seed 3 --depth 0", "--depth: expected a value in [1, 64], found 0"},
  };
  for (const std::string& command : commands) {
    for (const Case& c : cases) {
      CAPTURE(command + c.args);
      const test::CommandResult r = test::run_command("timeout 20 " + test::rayfarm_exe() + " " + command + c.args);
      CHECK(r.exit_code != 0);
      CHECK(r.output.find(c.message) != std::string::npos);
    }
  }
  // --adaptive's value is optional, so it takes the scene written after it:
  // the error says so instead of "Could not convert".
  for (const std::string name : {"render", "broker", "submit"}) {
    CAPTURE(name);
    const test::CommandResult r =
        test::run_command(test::rayfarm_exe() + " " + name + " --adaptive " + scene + out);
    CHECK(r.exit_code != 0);
    CHECK(r.output.find("is not a contrast: --adaptive takes the next word as its value") != std::string::npos);
  }
  std::filesystem::remove_all(dir);
}
