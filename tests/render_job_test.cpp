// render_job: settings derived from the scene plus overrides, row bands, the
// stats JSON, and the `rayfarm render` command line run as a real process.
#include <doctest/doctest.h>

#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>

#include "tests/run_command.h"
#include "tests/test_paths.h"
#include "tracer/error.h"
#include "tracer/image_io.h"
#include "tracer/nff_reader.h"
#include "tracer/render_job.h"
#include "tracer/renderer.h"

namespace fs = std::filesystem;
using namespace rayfarm;

namespace {

// Two spheres over a floor, one light: small, but every code path of a job.
const char* kScene = R"(b 0.1 0.2 0.3
v
from 0 -4 1
at 0 0 0
up 0 0 1
angle 40
hither 0.01
resolution 40 30
l 3 -3 5
f 1 0.5 0.5 0.8 0.3 20 0 1
s -0.6 0 0 0.5
s 0.6 0 0 0.5
f 0.8 0.8 0.8 1 0 0 0 1
p 4
-3 -3 -0.5
3 -3 -0.5
3 3 -0.5
-3 3 -0.5
)";

fs::path temp_dir() {
  fs::path dir = fs::temp_directory_path() / ("rayfarm-render-job-" + std::to_string(::getpid()));
  fs::create_directories(dir);
  return dir;
}

fs::path write_scene(const fs::path& dir) {
  const fs::path path = dir / "scene.nff";
  std::ofstream(path) << kScene;
  return path;
}

std::string rayfarm_cmd(const std::string& args) { return test::rayfarm_exe() + " " + args; }

}  // namespace

TEST_CASE("render_job: settings come from the scene unless overridden") {
  const Scene scene = parse_nff(kScene, "t.nff");
  RenderOverrides o;
  RenderSettings s = derive_settings(scene, o);
  CHECK(s.width == 40);
  CHECK(s.height == 30);
  CHECK(s.spp == 16);
  CHECK(s.max_depth == 5);

  o.width = 80;  // height follows the scene's aspect ratio
  s = derive_settings(scene, o);
  CHECK(s.width == 80);
  CHECK(s.height == 60);
}

TEST_CASE("render_job: bad settings are rejected with the setting's name") {
  const Scene scene = parse_nff(kScene, "t.nff");
  RenderOverrides o;
  o.spp = 10;
  CHECK_THROWS_WITH_AS(derive_settings(scene, o), doctest::Contains("spp must be a perfect square"), InputError);
  o = {};
  o.max_depth = 0;
  CHECK_THROWS_WITH_AS(derive_settings(scene, o), doctest::Contains("depth must be between"), InputError);
  o = {};
  o.width = 0;
  CHECK_THROWS_WITH_AS(derive_settings(scene, o), doctest::Contains("width must be between"), InputError);
  o = {};
  o.cutoff = -0.1;
  CHECK_THROWS_WITH_AS(derive_settings(scene, o), doctest::Contains("cutoff must be between 0 and 1"), InputError);
  o.cutoff = 0.001;
  o.adaptive_contrast = 0.2;
  const RenderSettings s = derive_settings(scene, o);
  CHECK(s.cutoff == 0.001);
  CHECK(s.adaptive_contrast == 0.2);
}

TEST_CASE("render_job: row ranges parse and are checked against the image") {
  const RowRange r = parse_rows("3:17");
  CHECK(r.y0 == 3);
  CHECK(r.y1 == 17);
  CHECK_THROWS_AS(parse_rows("3-17"), InputError);
  CHECK_THROWS_AS(parse_rows("a:4"), InputError);
  CHECK_THROWS_AS(parse_rows("4:"), InputError);
  CHECK_NOTHROW(check_rows({0, 30}, 30));
  CHECK_THROWS_AS(check_rows({0, 31}, 30), InputError);
  CHECK_THROWS_AS(check_rows({5, 5}, 30), InputError);
  CHECK_THROWS_AS(check_rows({-1, 5}, 30), InputError);
}

TEST_CASE("render_job: a job writes the image and stats with the documented keys") {
  const fs::path dir = temp_dir();
  RenderJob job;
  job.scene_path = write_scene(dir).string();
  job.output_path = (dir / "out.exr").string();
  job.stats_path = (dir / "stats.json").string();
  job.overrides.spp = 4;
  const RenderReport report = run_render_job(job);
  CHECK(report.rays.eye == 40u * 30u * 4u);
  CHECK(report.rays.shadow > 0);
  CHECK(report.rays.reflection > 0);
  CHECK(report.rays.refraction == 0);

  const RgbImage image = read_image(job.output_path);
  CHECK(image.width == 40);
  CHECK(image.height == 30);

  nlohmann::json stats;
  std::ifstream(job.stats_path) >> stats;
  for (const char* key : {"parse", "build", "render"}) CHECK(stats["seconds"].contains(key));
  for (const char* key : {"eye", "shadow", "reflection", "refraction"}) CHECK(stats["rays"].contains(key));
  CHECK(stats["rays"]["eye"] == 4800);
  CHECK(stats["non_finite_samples"] == 0);
  CHECK(stats["effects"] == nlohmann::json({"shadows", "reflection"}));
  CHECK(stats["width"] == 40);
  CHECK(stats["height"] == 30);
  CHECK(stats["spp"] == 4);
  CHECK(stats.contains("mrays_per_s"));
  fs::remove_all(dir);
}

TEST_CASE("render_job: the command renders, and a band equals the same rows of the full image") {
  const fs::path dir = temp_dir();
  const std::string scene = write_scene(dir).string();
  const std::string full = (dir / "full.exr").string();
  const std::string band = (dir / "band.exr").string();
  REQUIRE(test::run_command(rayfarm_cmd("render " + scene + " -o " + full + " --spp 4")).exit_code == 0);
  REQUIRE(test::run_command(rayfarm_cmd("render " + scene + " -o " + band + " --spp 4 --rows 10:20")).exit_code == 0);
  const RgbImage a = read_image(full);
  const RgbImage b = read_image(band);
  REQUIRE(b.height == 10);
  const size_t row = 3 * static_cast<size_t>(a.width);
  CHECK(std::equal(b.rgb.begin(), b.rgb.end(), a.rgb.begin() + 10 * row));
  fs::remove_all(dir);
}

TEST_CASE("render_job: progress comes in bands that cost nothing, and they render the same floats") {
  const Scene scene = parse_nff(kScene, "scene.nff");
  for (const double contrast : {0.0, 0.1}) {  // uniform: 8-row tiles; adaptive: 64-row blocks
    RenderOverrides o;
    o.height = 300;
    o.spp = 4;
    o.adaptive_contrast = contrast;
    const Renderer renderer(scene, derive_settings(scene, o));
    const RowRange rows{3, 300};
    std::vector<float> whole, banded;
    RayStats whole_rays, banded_rays;
    render_band(renderer, rows, whole, whole_rays);
    std::vector<int> done;
    render_band(renderer, rows, banded, banded_rays, [&](int d, int total) {
      CHECK(total == rows.count());
      done.push_back(d);
    });
    CHECK(banded == whole);
    CHECK(banded_rays.total() == whole_rays.total());
    REQUIRE(done.size() >= 3);
    CHECK(done.front() == 0);
    CHECK(done.back() == rows.count());
    for (size_t i = 1; i + 1 < done.size(); ++i) CHECK(done[i] % renderer.band_rows() == 0);
    CHECK(renderer.band_rows() == (contrast > 0 ? 64 : 8));
  }
}

TEST_CASE("render_job: command-line errors name the problem and exit non-zero") {
  const fs::path dir = temp_dir();
  const std::string scene = write_scene(dir).string();
  struct Case {
    std::string args;
    std::string message;
  } cases[] = {
      {"render " + (dir / "missing.nff").string() + " -o x.png", "missing.nff"},
      {"render " + scene + " -o " + (dir / "x.xyz").string(), "xyz"},
      {"render " + scene + " -o " + (dir / "x.png").string() + " --spp 10", "perfect square"},
      {"render " + scene + " -o " + (dir / "x.png").string() + " --rows 20:10", "--rows 20:10: expected Y0:Y1"},
      // Named by their options, where they were "width must be ...", "threads must be ...".
      {"render " + scene + " -o " + (dir / "x.png").string() + " --width 0", "--width: expected a value in [1, 65536], found 0"},
      {"render " + scene + " -o " + (dir / "x.png").string() + " --threads 5000", "--threads: expected a value in [0, 4096], found 5000"},
      // Were "cutoff must be ...", "adaptive contrast must be ..." and "spp must be ...", no option named.
      {"render " + scene + " -o " + (dir / "x.png").string() + " --cutoff 2",
       "--cutoff: expected a finite number in [0, 1], found 2"},
      {"render " + scene + " -o " + (dir / "x.png").string() + " --adaptive -1",
       "--adaptive: expected a finite number in [0, 1e+30], found -1"},
      {"render " + scene + " -o " + (dir / "x.png").string() + " --adaptive=nan",
       "--adaptive: expected a finite number in [0, 1e+30], found nan"},
      {"render " + scene + " -o " + (dir / "x.png").string() + " --spp 10",
       "--spp: expected a perfect square k*k (1, 4, 9, 16, 25, ...), found 10"},
      {"broker " + scene + " -o " + (dir / "x.png").string() + " --cutoff -0.5",
       "--cutoff: expected a finite number in [0, 1], found -0.5"},
      {"submit " + scene + " --spp 8", "--spp: expected a perfect square k*k (1, 4, 9, 16, 25, ...), found 8"},
      {"render " + scene + " -o " + (dir / "nodir" / "x.png").string(), "cannot write"},
      {"render " + scene + " -o " + (dir / "nodir" / "x.png").string() + " --workers 2", "cannot write"},
      {"render " + scene + " -o " + (dir / "x.png").string() + " --workers 2 --rows 0:10", "--rows"},
      {"render " + scene + " -o " + (dir / "x.png").string() + " --farm-record " + (dir / "r.json").string(),
       "--farm-record"},
      {"render " + scene, "--output"},
      // '' would read as an option not given; a minus sign as an unsigned option's largest value.
      {"render " + scene + " -o ''", "-o: empty value"},
      {"render " + scene + " -o " + (dir / "x.png").string() + " --stats ''", "--stats: empty value"},
      {"render " + scene + " -o " + (dir / "x.png").string() + " --workers 1 --farm-record ''",
       "--farm-record: empty value"},
      {"render " + scene + " -o " + (dir / "x.png").string() + " --seed -1", "--seed: expected a number >= 0"},
      {"render " + scene + " -o " + (dir / "x.png").string() + " --seed 18446744073709551616",
       "--seed: larger than 18446744073709551615"},
      // A scene path that never ends: refused at the scene limit, where it read until std::bad_alloc.
      {"render /dev/zero -o " + (dir / "x.png").string(), "/dev/zero: larger than the 256 MiB scene limit"},
      // One file under two options: the later write would replace the image, or the scene.
      {"render " + scene + " -o " + (dir / "x.png").string() + " --stats " + (dir / "." / "x.png").string(),
       "--stats " + (dir / "." / "x.png").string() + " is the same file as -o"},
      {"render " + scene + " -o " + (dir / "x.png").string() + " --stats " + scene,
       "--stats " + scene + " is the same file as the scene"},
      {"render " + scene + " -o " + (dir / "x.png").string() + " --workers 1 --farm-record " + (dir / "x.png").string(),
       "--farm-record " + (dir / "x.png").string() + " is the same file as -o"},
  };
  for (const Case& c : cases) {
    CAPTURE(c.args);
    const test::CommandResult r = test::run_command(rayfarm_cmd(c.args));
    CHECK(r.exit_code != 0);
    CHECK(r.output.find(c.message) != std::string::npos);
  }
  const std::string help = test::run_command(rayfarm_cmd("render --help")).output;
  CHECK(help.find("--spp") != std::string::npos);
  // Rayshade's cutoff is 0.002 on a weight of its own (README, Speed), not 0.001.
  CHECK(help.find("Rayshade's default, 0.002") != std::string::npos);
  fs::remove_all(dir);
}

TEST_CASE("render_job: whole-number options take decimal digits and say what they found") {
  // CLI11 said "--spp: Value 3.0 not in range 1 to 65536" and read 010 as octal 8.
  const fs::path dir = temp_dir();
  const std::string scene = write_scene(dir).string(), out = (dir / "x.png").string();
  for (const std::string bad :
       {"--spp 3.0", "--width abc", "--width 0x10", "--depth 1e1", "--seed 1.5", "--width 8x"}) {
    CAPTURE(bad);
    const test::CommandResult r = test::run_command(rayfarm_cmd("render " + scene + " -o " + out + " " + bad));
    CHECK(r.exit_code != 0);
    const std::string option = bad.substr(0, bad.find(' ')), value = bad.substr(bad.find(' ') + 1);
    CHECK(r.output.find(option + ": expected a whole number, found " + value) != std::string::npos);
  }
  // Every command's: spd's said "Could not convert: --size = 2.5" (named as typed).
  const test::CommandResult spd = test::run_command(rayfarm_cmd("spd tetra -s 2.5"));
  CHECK(spd.exit_code != 0);
  CHECK(spd.output.find("-s: expected a whole number, found 2.5") != std::string::npos);
  const std::string stats = (dir / "stats.json").string();
  const test::CommandResult r = test::run_command(
      rayfarm_cmd("render " + scene + " -o " + out + " --width 010 --spp 09 --depth +3 --stats " + stats));
  REQUIRE(r.exit_code == 0);
  nlohmann::json json;
  std::ifstream(stats) >> json;
  CHECK(json["width"] == 10);
  CHECK(json["spp"] == 9);
  CHECK(json["depth"] == 3);
  fs::remove_all(dir);
}

TEST_CASE("render_job: more --threads than the machine has render on its threads, said in rayfarm's words") {
  // TBB gave the arena no more than the machine's threads anyway, with a
  // "TBB Warning" of its own, and the stats counted the threads asked for.
  const fs::path dir = temp_dir();
  const std::string scene = write_scene(dir).string(), stats = (dir / "stats.json").string();
  const test::CommandResult r = test::run_command(rayfarm_cmd("render " + scene + " -o " + (dir / "x.png").string() +
                                                              " --spp 1 --threads 4096 --stats " + stats));
  CHECK(r.exit_code == 0);
  const int machine = render_threads(0);
  CHECK(r.output.find("warning: --threads 4096: this machine runs " + std::to_string(machine) +
                      " threads at once; rendering on " + std::to_string(machine)) != std::string::npos);
  CHECK(r.output.find("TBB") == std::string::npos);
  nlohmann::json json;
  std::ifstream(stats) >> json;
  CHECK(json["threads"] == machine);
  CHECK(render_threads(4096) == machine);
  CHECK(render_threads(1) == 1);
  fs::remove_all(dir);
}

TEST_CASE("render_job: an unknown --max-isa is refused once, before a local farm starts its workers") {
  // Each worker refused it on its own, and the render then failed with "all 2 local workers exited".
  const fs::path dir = temp_dir();
  const std::string scene = write_scene(dir).string();
  for (const std::string workers : {"0", "2"}) {
    CAPTURE(workers);
    const test::CommandResult r = test::run_command(
        rayfarm_cmd("render " + scene + " -o " + (dir / "x.png").string() + " --max-isa avx3 --workers " + workers));
    CHECK(r.exit_code == 1);
    CHECK(r.output ==
          "rayfarm: --max-isa: max_isa must be one of sse2, sse4.2, avx, avx2, avx512 (or empty: no cap), got \"avx3\"\n");
  }
  CHECK(!fs::exists(dir / "x.png"));
  fs::remove_all(dir);
}

TEST_CASE("render_job: render --workers into a log writes what the in-process render writes, no progress lines") {
  // Its broker's progress went to a pipe as "rayfarm broker: rows 0/32 ..." lines.
  const fs::path dir = temp_dir();
  const std::string scene = write_scene(dir).string();
  for (const std::string workers : {"0", "2"}) {
    CAPTURE(workers);
    const test::CommandResult r = test::run_command(
        rayfarm_cmd("render " + scene + " -o " + (dir / "x.png").string() + " --workers " + workers));
    CHECK(r.exit_code == 0);
    CHECK(r.output.find("rayfarm broker:") == std::string::npos);
    CHECK(r.output.find("x.png: ") != std::string::npos);  // the summary line
  }
  fs::remove_all(dir);
}

TEST_CASE("render_job: a scene from a FIFO renders, and one of endless data is refused at the scene limit") {
  const fs::path dir = temp_dir();
  const std::string fifo = (dir / "scene.fifo").string();
  const std::string out = (dir / "x.png").string();
  auto render_from_fifo = [&](const std::string& writer) {
    fs::remove(fifo);
    // The writer blocks until rayfarm opens the FIFO, and ends when it closes it (SIGPIPE).
    return test::run_command("mkfifo " + fifo + " && (timeout 60 " + writer + " > " + fifo + " &) && " +
                             rayfarm_cmd("render " + fifo + " -o " + out));
  };
  const test::CommandResult scene = render_from_fifo("cat " + write_scene(dir).string());
  CHECK(scene.exit_code == 0);
  CHECK(fs::exists(out));
  fs::remove(out);
  const test::CommandResult endless = render_from_fifo("cat /dev/zero");
  CHECK(endless.exit_code == 1);
  CHECK(endless.output == "rayfarm: " + fifo + ": larger than the 256 MiB scene limit\n");
  CHECK(!fs::exists(out));
  fs::remove_all(dir);
}

TEST_CASE("render_job: --adaptive takes an optional contrast, --cutoff prunes the tree") {
  const fs::path dir = temp_dir();
  const std::string scene = write_scene(dir).string();
  auto rays = [&](const std::string& flags) {
    const std::string stats = (dir / "stats.json").string();
    const std::string cmd = "render " + scene + " -o " + (dir / "x.png").string() + " --stats " + stats + flags;
    REQUIRE(test::run_command(rayfarm_cmd(cmd)).exit_code == 0);
    nlohmann::json j;
    std::ifstream(stats) >> j;
    return j["rays"];
  };
  const auto full = rays("");
  // A bare --adaptive (contrast 0.1, the default) traces fewer eye rays than
  // uniform 16 spp; --adaptive 0 is uniform sampling again.
  const auto bare = rays(" --adaptive");
  CHECK(bare["eye"] < full["eye"]);
  CHECK(bare == rays(" --adaptive 0.1"));
  CHECK(bare != rays(" --adaptive 0.15"));  // so the check above names the default
  CHECK(rays(" --adaptive --cutoff 0.5")["eye"] < full["eye"]);
  CHECK(rays(" --adaptive 0") == full);
  CHECK(rays(" --cutoff 0.5")["reflection"] < full["reflection"]);
  fs::remove_all(dir);
}

TEST_CASE("render_job: rayfarm renders without the farm's libraries and hands other commands to rayfarm-farm") {
  // What a one-shot render loads: no ZeroMQ, HTTP or TLS (app/main.cpp).
  const test::CommandResult libs = test::run_command("ldd " + test::rayfarm_exe());
  REQUIRE(libs.exit_code == 0);
  CHECK(libs.output.find("libembree3") != std::string::npos);
  CHECK(libs.output.find("libzmq") == std::string::npos);
  CHECK(libs.output.find("httplib") == std::string::npos);
  CHECK(libs.output.find("libssl") == std::string::npos);
  // The farm's commands still answer through the same command.
  CHECK(test::run_command(rayfarm_cmd("broker --help")).output.find("--key") != std::string::npos);
  CHECK(test::run_command(rayfarm_cmd("--help")).output.find("worker") != std::string::npos);
}
