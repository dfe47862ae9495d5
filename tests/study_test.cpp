// The accuracy study: image metrics, the equal-time interpolation, Pareto
// fronts, the reference cache, and a tiny end-to-end study (library and
// `rayfarm study`) whose CSV must have the documented shape, whose PSNR must
// grow with the sample count and whose fronts must be non-dominated.
#include <doctest/doctest.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "study/image_metrics.h"
#include "study/pareto.h"
#include "study/plot_script.h"
#include "study/quality_study.h"
#include "study/reference_cache.h"
#include "study/study_knobs.h"
#include "study/study_report.h"
#include "tests/run_command.h"
#include "tests/test_paths.h"
#include "tracer/error.h"
#include "tracer/nff_reader.h"
#include "tracer/text_file.h"

namespace rayfarm {
namespace {

std::vector<std::vector<std::string>> read_csv(const std::string& path) {
  std::ifstream in(path);
  std::vector<std::vector<std::string>> rows;
  std::string line;
  while (std::getline(in, line)) {
    std::vector<std::string> cells;
    std::stringstream ss(line);
    std::string cell;
    while (std::getline(ss, cell, ',')) cells.push_back(cell);
    if (!line.empty() && line.back() == ',') cells.emplace_back();
    rows.push_back(cells);
  }
  return rows;
}

StudyOptions tiny_options(const std::string& out_dir) {
  StudyOptions o;
  o.scene_name = "balls-2";
  o.out_dir = out_dir;
  o.size = 16;
  o.reference_spp = 256;
  o.spp_list = {1, 4, 16, 64};
  o.reference_depth = 6;
  o.base_spp = 4;
  o.base_depth = 3;
  o.depth_list = {1, 3, 6};
  o.adaptive_spp = {16};
  o.adaptive_thresholds = {0.2, 0.05};
  // 1e-12 is below every path weight at these depths: it must prune nothing.
  o.cutoffs = {0, 1e-12, 0.1, 0.3};
  o.cutoff_depth = 3;  // the base depth: cutoff 0 is the base setting
  o.threads = 2;
  o.repeats = 1;
  o.min_timed_seconds = 0;
  return o;
}

std::string tiny_scene() { return test::spd_data("balls-2"); }

// The tiny options with no images and only the knobs a test names: the spp
// sweep keeps one value (the base spp), the other sweeps are emptied.
StudyOptions only_knobs(StudyOptions o) {
  o.write_images = false;
  o.spp_list = {o.base_spp};
  o.depth_list = {};
  o.adaptive_spp = {};
  o.cutoffs = {};
  o.robust = false;
  return o;
}

std::string read_text(const std::string& path) {
  std::ifstream in(path);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

// Every row on a front is dominated by no row of its set, and every row off it
// by some row: the fronts the study writes are the fronts of its numbers.
void check_fronts(const std::vector<const StudyRow*>& rows, bool StudyRow::*flag, bool by_rays) {
  const auto point = [by_rays](const StudyRow* r) {
    return CostQuality{by_rays ? static_cast<double>(r->rays.total()) : r->seconds, r->diff.psnr};
  };
  for (const StudyRow* a : rows) {
    bool dominated = false;
    for (const StudyRow* b : rows) dominated = dominated || dominates(point(b), point(a));
    INFO(a->sweep << " " << a->value << ": " << point(a).cost << ", " << point(a).psnr << " dB");
    CHECK(a->*flag == !dominated);
  }
}

// A fresh directory under the system temp dir, unique per test process (other
// checkouts may run this test at the same time), removed again with its side
// files (dir.out, dir.err, ...) when the test ends.
struct TempDir {
  std::string path;
  explicit TempDir(const std::string& name)
      : path((std::filesystem::temp_directory_path() /
              ("rayfarm_study_test_" + name + "_" + std::to_string(::getpid())))
                 .string()) {
    clean();
  }
  ~TempDir() { clean(); }
  void clean() const {
    std::error_code ec;
    std::filesystem::remove_all(path, ec);
    for (const char* ext : {".out", ".err", ".bad"}) std::filesystem::remove(path + ext, ec);
  }
};

}  // namespace

TEST_CASE("study: image metrics on known images") {
  const std::vector<float> a{0, 0, 0, 1, 1, 1};
  std::vector<float> b{0, 0, 0, 1, 1, 1};
  ImageDiff d = compare_images(a, b);
  CHECK(d.rmse == 0);
  CHECK(std::isinf(d.psnr));
  CHECK(d.pixels_over == 0);
  b[0] = 0.5f;  // one channel of six off by 0.5: MSE 0.25/6
  d = compare_images(a, b);
  CHECK(d.rmse == doctest::Approx(std::sqrt(0.25 / 6)));
  CHECK(d.psnr == doctest::Approx(20 * std::log10(1 / std::sqrt(0.25 / 6))));
  CHECK(d.max_abs == doctest::Approx(0.5));
  CHECK(d.mean_abs == doctest::Approx(0.5 / 6));
  CHECK(d.pixels_over == 1);
  // Display clamping: 3.0 vs 2.0 is white vs white.
  const std::vector<float> hot{3, 3, 3}, warm{2, 2, 2};
  CHECK(compare_images(hot, warm).rmse == 0);
  CHECK(compare_images(hot, warm, {false, 1.0 / 255}).rmse == doctest::Approx(1.0));
  CHECK(psnr_from_rmse(0.1) == doctest::Approx(20.0));
}

TEST_CASE("study: NaN and size mismatches do not pass silently") {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const std::vector<float> a{0.5f, 0.5f, 0.5f}, b{nan, 0.5f, 0.5f};
  CHECK(count_non_finite(b) == 1);
  CHECK_FALSE(all_finite(b));
  CHECK(all_finite(a));
  CHECK(std::isinf(compare_images(a, b).max_abs));
  CHECK_THROWS_AS(compare_images(a, std::vector<float>{1, 2}), std::invalid_argument);
  CHECK(count_black_pixels({0, 0, 0, 0, 0.1f, 0}) == 1);
}

TEST_CASE("study: equal-cost and equal-quality interpolation in log cost") {
  const std::vector<CostQuality> uniform{{4.0, 30}, {1.0, 20}, {16.0, 40}};  // unsorted on purpose
  CHECK(psnr_at_cost(uniform, 2.0) == doctest::Approx(25));  // halfway in log cost
  CHECK(psnr_at_cost(uniform, 16.0) == doctest::Approx(40));
  CHECK(std::isnan(psnr_at_cost(uniform, 0.5)));  // outside the sweep
  CHECK(cost_for_psnr(uniform, 35) == doctest::Approx(8.0));
  CHECK(std::isnan(cost_for_psnr(uniform, 50)));
}

TEST_CASE("study: options are validated with the option's name") {
  StudyOptions o;
  o.reference_spp = 1000;
  CHECK_THROWS_WITH_AS(validate(o), doctest::Contains("--reference-spp"), InputError);
  o = StudyOptions{};
  o.spp_list = {1, 8};
  CHECK_THROWS_WITH_AS(validate(o), doctest::Contains("spp 8"), InputError);
  o = StudyOptions{};
  o.adaptive_thresholds = {0};
  CHECK_THROWS_AS(validate(o), InputError);
  // Named as the options, where they failed as "cutoff 0: depth ..." and mid-study.
  o = StudyOptions{};
  o.cutoff_depth = 0;
  CHECK_THROWS_WITH_AS(validate(o), doctest::Contains("--cutoff-depth must be in 1..64, found 0"), InputError);
  o = StudyOptions{};
  o.threads = -1;
  CHECK_THROWS_WITH_AS(validate(o), doctest::Contains("--threads must be in 0..4096, found -1"), InputError);
  // Each with the value found.
  o = StudyOptions{};
  o.size = 0;
  CHECK_THROWS_WITH_AS(validate(o), doctest::Contains("--size must be in 1..8192, found 0"), InputError);
  o = StudyOptions{};
  o.repeats = 101;
  CHECK_THROWS_WITH_AS(validate(o), doctest::Contains("--repeats must be in 1..100, found 101"), InputError);
  o = StudyOptions{};
  o.min_timed_seconds = std::nan("");
  CHECK_THROWS_WITH_AS(validate(o), doctest::Contains("--min-time must be a finite number >= 0, found nan"),
                       InputError);
  o = StudyOptions{};
  o.adaptive_thresholds = {0.1, 0};
  CHECK_THROWS_WITH_AS(validate(o), doctest::Contains("--contrast values must be > 0, found 0"), InputError);
  o = StudyOptions{};
  // Named as the option: "cutoff -0.5: cutoff must be between 0 and 1, found -0.500000" named the sweep.
  o.cutoffs = {0, 2};
  CHECK_THROWS_WITH_AS(validate(o), doctest::Contains("--cutoffs values must be in [0, 1], found 2"), InputError);
  o.cutoffs = {-0.5};
  CHECK_THROWS_WITH_AS(validate(o), doctest::Contains("--cutoffs values must be in [0, 1], found -0.5"), InputError);
  o = StudyOptions{};
  o.presets = {"cutoff=-0.5"};
  CHECK_THROWS_WITH_AS(validate(o), doctest::Contains("preset cutoff=-0.5: cutoff must be between 0 and 1, found -0.5"),
                       InputError);
  o = StudyOptions{};
  o.presets = {"spp=64,dpeth=8"};
  CHECK_THROWS_WITH_AS(validate(o), doctest::Contains("unknown key \"dpeth\""), InputError);
  o.presets = {"spp=10"};
  CHECK_THROWS_WITH_AS(validate(o), doctest::Contains("preset spp=10: spp must be a perfect square"), InputError);
  o.presets = {"spp=sixteen"};
  CHECK_THROWS_WITH_AS(validate(o), doctest::Contains("\"spp=sixteen\" is not key=number"), InputError);
  // Not cut to 16 spp and 5 under the names "spp=16.5" and "depth=5.9".
  o.presets = {"spp=16.5"};
  CHECK_THROWS_WITH_AS(validate(o), doctest::Contains("\"spp=16.5\": spp is a whole number"), InputError);
  o.presets = {"depth=5.9"};
  CHECK_THROWS_WITH_AS(validate(o), doctest::Contains("\"depth=5.9\": depth is a whole number"), InputError);
  o.presets = {"spp=4,depth=3,spp=16"};
  CHECK_THROWS_WITH_AS(validate(o), doctest::Contains("preset \"spp=4,depth=3,spp=16\": \"spp\" given twice"),
                       InputError);
  o.presets = {"spp=1e10"};
  CHECK_THROWS_WITH_AS(validate(o), doctest::Contains("spp must be between 1 and 65536"), InputError);
  o.presets = {"robust=2"};
  CHECK_THROWS_WITH_AS(validate(o), doctest::Contains("robust is 0 (off) or 1 (on)"), InputError);
}

TEST_CASE("study: a study with every sweep left out is refused before the reference is rendered") {
  StudyOptions o;
  o.spp_list.clear();
  o.depth_list.clear();
  o.adaptive_spp.clear();
  o.cutoffs.clear();
  o.robust = false;
  CHECK_THROWS_WITH_AS(validate(o), doctest::Contains("study: nothing to sweep"), InputError);
  o.presets = {"spp=4"};
  CHECK_NOTHROW(validate(o));
  o.presets.clear();
  o.robust = true;
  CHECK_NOTHROW(validate(o));
  // From the command line: refused at once, no reference rendered, nothing written.
  const TempDir tmp("no-sweep");
  const test::CommandResult r = test::run_command(
      test::rayfarm_exe() + " study " + test::spd_data("tetra-1") +
      " --spp --depths --adaptive-spp --contrast --cutoffs --no-robust --no-plots -o " + tmp.path + "/out");
  CHECK(r.exit_code == 1);
  CHECK(r.output.rfind("rayfarm: study: nothing to sweep", 0) == 0);
  CHECK(!std::filesystem::exists(tmp.path + "/out/reference.png"));
}

TEST_CASE("study: a preset sets several knobs, and one equal to the base is the base's render") {
  RenderSettings s;
  apply_preset("depth=8,spp=64,adaptive=0.05,cutoff=0.01,robust=1", s);
  CHECK(s.spp == 64);
  CHECK(s.max_depth == 8);
  CHECK(s.adaptive_contrast == 0.05);
  CHECK(s.cutoff == 0.01);
  CHECK(s.robust_bvh);
  const Scene scene = read_nff_file(tiny_scene());
  StudyOptions o = only_knobs(tiny_options(""));
  o.presets = {"spp=4,depth=3", "spp=16,depth=6,cutoff=0.1"};
  const StudyResult result = run_study(scene, o);
  const auto presets = rows_of(result, "preset");
  REQUIRE(presets.size() == 2);
  CHECK(presets[0]->reused);  // spp 4, depth 3 is the tiny base
  CHECK(presets[1]->settings.spp == 16);
  CHECK(presets[1]->settings.max_depth == 6);
  CHECK(presets[1]->settings.cutoff == 0.1);
  CHECK(presets[1]->diff.psnr > presets[0]->diff.psnr);
}

TEST_CASE("study: a tiny study writes a CSV of the documented shape and PSNR grows with spp") {
  const Scene scene = read_nff_file(tiny_scene());
  const TempDir tmp("lib");
  const StudyOptions o = tiny_options(tmp.path);
  int progress_lines = 0;
  const StudyResult result = run_study(scene, o, [&](const std::string&) { ++progress_lines; });
  CHECK(progress_lines > 10);
  const StudyFiles files = write_study(result, o, true, test::source_dir() + "/scripts/plot_study.py");
  if (find_plot_python().empty()) {
    MESSAGE("no python3 with matplotlib: plots not checked (" << files.plots.note << ")");
  } else {
    INFO(files.plots.note);
    CHECK(files.plots.files == std::vector<std::string>{"knobs.png", "pareto.png", "depth.png"});
    for (const std::string& png : files.plots.files) CHECK(std::filesystem::file_size(o.out_dir + "/" + png) > 1000);
  }
  const auto rows = read_csv(files.csv);
  const size_t columns = study_csv_columns().size();
  // Header, reference, 4 spp, 3 depths, 2 adaptive, 4 cutoffs, 2 robust.
  REQUIRE(rows.size() == 1 + 1 + 4 + 3 + 2 + 4 + 2);
  CHECK(rows[0] == study_csv_columns());
  for (const auto& row : rows) CHECK(row.size() == columns);
  CHECK(rows[1][1] == "reference");

  const auto spp = rows_of(result, "spp");
  REQUIRE(spp.size() == 4);
  for (size_t i = 1; i < spp.size(); ++i) {
    INFO("spp " << spp[i]->settings.spp << ": " << spp[i]->diff.psnr << " dB after " << spp[i - 1]->diff.psnr);
    CHECK(spp[i]->diff.psnr > spp[i - 1]->diff.psnr);
    CHECK(spp[i]->rays.eye == 4 * spp[i - 1]->rays.eye);
  }
  // The deepest depth row is the depth knob's exact member; adaptive never
  // traces more eye rays than uniform at its spp.
  const auto depth = rows_of(result, "depth");
  CHECK(std::isinf(depth.back()->knob_diff.psnr));
  CHECK(depth.front()->knob_diff.psnr < depth[1]->knob_diff.psnr);
  for (const StudyRow* row : rows_of(result, "adaptive")) CHECK(row->rays.eye <= 16u * 16 * 16);
  // Robust traversal against plain, same samples: close, and "on" is its own exact member.
  const auto robust = rows_of(result, "robust");
  REQUIRE(robust.size() == 2);
  CHECK(std::isinf(robust[1]->knob_diff.psnr));
  CHECK(robust[0]->knob_diff.psnr > 30);
  for (const StudyRow& row : result.rows) CHECK(row.non_finite == 0);
  std::ifstream md(files.markdown);
  const std::string text((std::istreambuf_iterator<char>(md)), std::istreambuf_iterator<char>());
  CHECK(text.find("## spp") != std::string::npos);
  CHECK(text.find("## Pareto front over all knobs") != std::string::npos);
  CHECK(text.find("The SPD setting (spp 4, depth 3)") != std::string::npos);
}

TEST_CASE("study: the base setting is rendered once and reused by every sweep that contains it") {
  const Scene scene = read_nff_file(tiny_scene());
  StudyOptions o = tiny_options("");
  o.write_images = false;
  std::vector<std::string> lines;
  const StudyResult result = run_study(scene, o, [&](const std::string& l) { lines.push_back(l); });
  const StudyRow* base = base_row(result);
  REQUIRE(base != nullptr);
  CHECK(base->sweep == "spp");
  CHECK_FALSE(base->reused);
  size_t copies = 0;
  for (const StudyRow& row : result.rows) {
    if (settings_key(row.settings) != settings_key(result.base)) continue;
    ++copies;
    CHECK(row.seconds == base->seconds);
    CHECK(row.diff.psnr == base->diff.psnr);
    CHECK(row.reused == (&row != base));
  }
  CHECK(copies == 4);  // spp 4, depth 3, cutoff 0, robust off
  size_t said_reused = 0;
  for (const std::string& l : lines) said_reused += l.find("reused") != std::string::npos;
  CHECK(said_reused == 3);
}

TEST_CASE("study: every sweep's Pareto fronts and the front over all knobs are non-dominated") {
  const Scene scene = read_nff_file(tiny_scene());
  StudyOptions o = tiny_options("");
  o.write_images = false;
  const StudyResult result = run_study(scene, o);
  std::vector<const StudyRow*> all;
  for (const StudyRow& row : result.rows) {
    if (row.sweep != "reference") all.push_back(&row);
  }
  check_fronts(all, &StudyRow::front_all, false);
  check_fronts(all, &StudyRow::front_all_rays, true);
  size_t on_all = 0;
  for (const StudyRow* row : all) on_all += row->front_all;
  CHECK(on_all >= 1);
  for (const KnobInfo& knob : result.knobs) {
    INFO("knob " << knob.name);
    check_fronts(rows_of(result, knob.name), &StudyRow::front, false);
    check_fronts(rows_of(result, knob.name), &StudyRow::front_rays, true);
  }
  // By rays the uniform spp sweep is a strict ladder: each step costs more and
  // (from 1 spp on) is better, so all of it is on its front.
  for (const StudyRow* row : rows_of(result, "spp")) CHECK(row->front_rays);
}

TEST_CASE("study: cutoff 0 is the full tree bit for bit, and a larger cutoff traces fewer rays") {
  const Scene scene = read_nff_file(tiny_scene());
  StudyOptions o = only_knobs(tiny_options(""));
  o.cutoffs = {0, 1e-12, 0.1, 0.3};
  o.base_depth = 6;  // deep enough for the sphereflake's mirrors to leave weights to prune
  o.cutoff_depth = 6;
  const StudyResult result = run_study(scene, o);
  const auto cut = rows_of(result, "cutoff");
  REQUIRE(cut.size() == 4);
  const StudyRow* full = rows_of(result, "spp").front();
  // Cutoff 0 at the base depth is the base setting: the same render as the uniform row.
  CHECK(cut[0]->settings.cutoff == 0);
  CHECK(cut[0]->reused);
  CHECK(cut[0]->rays.total() == full->rays.total());
  CHECK(std::isinf(cut[0]->knob_diff.psnr));
  // A cutoff below every weight prunes nothing: identical bits and rays.
  CHECK(cut[1]->knob_diff.max_abs == 0);
  CHECK(cut[1]->rays.total() == full->rays.total());
  CHECK_FALSE(cut[1]->reused);  // a render of its own, not the base's
  // Larger cutoffs prune more: fewer secondary rays, never more, and the
  // eye rays stay. The image moves away from the full tree, but only a little.
  for (size_t i = 2; i < cut.size(); ++i) {
    INFO("cutoff " << cut[i]->value);
    CHECK(cut[i]->rays.total() < cut[i - 1]->rays.total());
    CHECK(cut[i]->rays.eye == full->rays.eye);
    CHECK(cut[i]->knob_diff.max_abs > 0);
    CHECK(cut[i]->knob_diff.psnr > 25);
  }
  CHECK(cut[3]->knob_diff.psnr < cut[2]->knob_diff.psnr);
}

TEST_CASE("study: Pareto fronts of known points") {
  // (cost, psnr): b beats a; c and d trade off; e ties c; f has no cost.
  const std::vector<CostQuality> pts{{2, 20}, {1, 25}, {4, 30}, {8, 35}, {4, 30}, {0, 99}, {3, std::nan("")}};
  CHECK(pareto_front(pts) == std::vector<bool>{false, true, true, true, true, false, false});
  CHECK(dominates({1, 25}, {2, 20}));
  CHECK_FALSE(dominates({4, 30}, {4, 30}));
  CHECK_FALSE(dominates({1, 25}, {4, 30}));
  // Random clouds (fixed seed): no front point is dominated, every other point is.
  uint64_t state = 12345;
  const auto next = [&state] {
    state = state * 6364136223846793005ULL + 1442695040888963407ULL;
    return static_cast<double>(state >> 11) / static_cast<double>(1ULL << 53);
  };
  for (int trial = 0; trial < 20; ++trial) {
    std::vector<CostQuality> cloud(30);
    for (CostQuality& p : cloud) p = {0.01 + next(), 10 + 30 * next()};
    const std::vector<bool> on = pareto_front(cloud);
    for (size_t i = 0; i < cloud.size(); ++i) {
      bool dominated = false;
      for (const CostQuality& q : cloud) dominated = dominated || dominates(q, cloud[i]);
      CHECK(on[i] == !dominated);
    }
  }
}

// The tiny scene's study with a reference cache, run once: the cache holds
// its reference, at `stem` (.exr and .json).
struct CachedStudy {
  const Scene scene = read_nff_file(tiny_scene());
  const TempDir tmp;
  StudyOptions o;
  StudyResult first;
  std::string stem;
  explicit CachedStudy(const std::string& name) : tmp(name), o(only_knobs(tiny_options(tmp.path + "/study"))) {
    o.reference_cache = tmp.path + "/refs";
    first = run_study(scene, o);
    stem = reference_cache_stem(o.reference_cache, o.scene_name, first.rows.front().settings);
  }
};

TEST_CASE("study: a cached reference is reused bit for bit and a stale one is re-rendered") {
  const CachedStudy study("cache");
  const auto& [scene, tmp, o, first, stem] = study;
  CHECK_FALSE(first.reference_cached);
  RenderSettings ref = first.rows.front().settings;
  REQUIRE(std::filesystem::exists(stem + ".exr"));
  REQUIRE(std::filesystem::exists(stem + ".json"));

  const StudyResult second = run_study(scene, o);
  CHECK(second.reference_cached);
  CHECK(second.rows.front().rays.total() == first.rows.front().rays.total());
  CHECK(second.rows[1].diff.psnr == first.rows[1].diff.psnr);  // the same reference, to the bit

  // Other settings are another entry; a sidecar that disagrees is no entry.
  ref.spp = 16;
  CHECK_FALSE(load_cached_reference(stem, ref, "").has_value());
  // A scene edited after the reference was made makes the entry stale.
  const std::string scene_copy = tmp.path + "/scene.nff";
  std::filesystem::copy_file(tiny_scene(), scene_copy);
  const auto made = std::filesystem::last_write_time(stem + ".exr");
  std::filesystem::last_write_time(scene_copy, made + std::chrono::seconds(5));
  CHECK_FALSE(load_cached_reference(stem, first.rows.front().settings, scene_copy).has_value());
  CHECK(load_cached_reference(stem, first.rows.front().settings, "").has_value());
  // A corrupt sidecar is an error naming the file, not a silent re-render.
  std::ofstream(stem + ".json") << "{\"width\": 16}";
  CHECK_THROWS_WITH_AS(load_cached_reference(stem, first.rows.front().settings, ""),
                       doctest::Contains(doctest::String((stem + ".json").c_str())), InputError);
}

TEST_CASE("study: a cached reference's sidecar is read with a limit, a huge one or a device refused at once") {
  const CachedStudy study("cache-limit");
  const auto& [scene, tmp, o, first, stem] = study;
  const RenderSettings& ref = first.rows.front().settings;
  const std::string sidecar = stem + ".json", text = read_text_file(sidecar);
  write_text_file(sidecar, text + std::string(2 << 20, ' '));  // valid JSON, 2 MiB of it
  REQUIRE_THROWS_WITH_AS(load_cached_reference(stem, ref, ""),
                         doctest::Contains(doctest::String((sidecar + ": larger than 1048576 bytes").c_str())),
                         InputError);
  std::filesystem::remove(sidecar);
  std::filesystem::create_symlink("/dev/zero", sidecar);  // read to its end, never ending
  CHECK_THROWS_WITH_AS(load_cached_reference(stem, ref, ""),
                       doctest::Contains(doctest::String((sidecar + ": not a regular file").c_str())), InputError);
  std::filesystem::remove(sidecar);
  write_text_file(sidecar, text);
  CHECK(load_cached_reference(stem, ref, "").has_value());
}

TEST_CASE("study: a corrupt cached reference is reported and rendered again, and the entry rewritten") {
  const CachedStudy study("corrupt-cache");
  const auto& [scene, tmp, o, first, stem] = study;
  const RenderSettings& ref = first.rows.front().settings;
  const struct {
    std::string file, text, problem;
  } corruptions[] = {{stem + ".json", "{\"width\": 16,", "invalid JSON"},
                     {stem + ".json", "{\"width\": 16, \"height\": 16}", "missing or malformed key spp"},
                     {stem + ".exr", "not an image", "not an OpenEXR file"}};
  for (const auto& c : corruptions) {
    CAPTURE(c.text);
    std::ofstream(c.file) << c.text;
    std::string said;
    const StudyResult again = run_study(scene, o, [&](const std::string& line) { said += line + "\n"; });
    // Said, naming the file and what is wrong, not a study stopped (or a silent re-render).
    CHECK(said.find(c.file) != std::string::npos);
    CHECK(said.find(c.problem) != std::string::npos);
    CHECK(said.find("rendering it again") != std::string::npos);
    CHECK_FALSE(again.reference_cached);
    CHECK(again.rows[1].diff.psnr == first.rows[1].diff.psnr);
    // The entry is whole again: the next study takes it.
    CHECK(load_cached_reference(stem, ref, "").has_value());
  }
}

TEST_CASE("study: a cached reference of another scene file with the same name is not taken") {
  // The entry's file name has the scene's name only: a/balls.nff and
  // b/balls.nff shared it, and b's study measured itself against a's image.
  const TempDir tmp("samename");
  const std::string a = tmp.path + "/a/scene.nff", b = tmp.path + "/b/scene.nff";
  std::filesystem::create_directories(tmp.path + "/a");
  std::filesystem::create_directories(tmp.path + "/b");
  std::filesystem::copy_file(tiny_scene(), a);
  std::filesystem::copy_file(tiny_scene(), b);
  StudyOptions o = only_knobs(tiny_options(tmp.path + "/study"));
  o.reference_cache = tmp.path + "/refs";
  o.scene_file = a;
  const StudyResult first = run_study(read_nff_file(a), o);
  CHECK_FALSE(first.reference_cached);
  const RenderSettings& ref = first.rows.front().settings;
  const std::string stem = reference_cache_stem(o.reference_cache, o.scene_name, ref);
  // b is older than the entry, so only its name can tell it from a.
  std::filesystem::last_write_time(b, std::filesystem::last_write_time(stem + ".exr") - std::chrono::hours(1));
  CHECK(load_cached_reference(stem, ref, a).has_value());
  CHECK_FALSE(load_cached_reference(stem, ref, b).has_value());
  o.scene_file = b;
  CHECK_FALSE(run_study(read_nff_file(b), o).reference_cached);
}

TEST_CASE("study: `rayfarm render --seed 1` writes a reference the cache takes as the study's own") {
  const Scene scene = read_nff_file(tiny_scene());
  const TempDir tmp("dropin");
  StudyOptions o = only_knobs(tiny_options(tmp.path + "/study"));
  o.reference_spp = 16;
  const StudyResult fresh = run_study(scene, o);
  const RenderSettings& ref = fresh.rows.front().settings;
  o.reference_cache = tmp.path + "/refs";
  const std::string stem = reference_cache_stem(o.reference_cache, o.scene_name, ref);
  std::filesystem::create_directories(o.reference_cache);
  const std::string cmd = test::rayfarm_exe() + " render " + tiny_scene() + " --width " + std::to_string(ref.width) +
                          " --height " + std::to_string(ref.height) + " --spp 16 --depth " +
                          std::to_string(ref.max_depth) + " --seed 1 --threads 2 -o " + stem + ".exr --stats " +
                          stem + ".json > /dev/null 2>&1";
  REQUIRE(std::system(cmd.c_str()) == 0);
  const StudyResult cached = run_study(scene, o);
  CHECK(cached.reference_cached);
  CHECK(cached.rows[1].diff.psnr == fresh.rows[1].diff.psnr);
  CHECK(cached.rows[1].diff.max_abs == fresh.rows[1].diff.max_abs);
}

TEST_CASE("study: `rayfarm study` writes study.csv and study.md") {
  const TempDir tmp("exe");
  const std::string& dir = tmp.path;
  const std::string scene = test::spd_data("balls-1");
  const std::string cmd = test::rayfarm_exe() + " study " + scene + " -o " + dir +
                          " --size 8 --reference-spp 16 --reference-depth 4 --base-spp 1 --base-depth 2"
                          " --spp 1 4 --depths 1 2 --adaptive-spp --cutoffs 0 0.1 --cutoff-depth 2"
                          " --preset spp=4,depth=3 --threads 2 --min-time 0 --no-plots"
                          " --reference-cache " + dir + "/refs > " + dir + ".out 2> " + dir + ".err";
  REQUIRE(std::system(cmd.c_str()) == 0);
  const auto rows = read_csv(dir + "/study.csv");
  // Header, reference, 2 spp, 2 depths, no adaptive ("--adaptive-spp" alone), 2 cutoffs, 1 preset, 2 robust.
  CHECK(rows.size() == 1 + 1 + 2 + 2 + 2 + 1 + 2);
  // The preset's commas are quoted in the CSV.
  CHECK(read_text(dir + "/study.csv").find(",preset,\"spp=4,depth=3\",4,3,") != std::string::npos);
  CHECK(std::filesystem::exists(dir + "/study.md"));
  const std::string progress = read_text(dir + ".err");
  CHECK(progress.find("study: balls-1 [1/10, ") != std::string::npos);
  CHECK(progress.find("reference 16 spp, depth 4") != std::string::npos);
  CHECK(std::filesystem::exists(dir + "/refs/balls-1-8x8-spp16-depth4-seed1.exr"));
  // A bad option is an error naming it, not a crash.
  const std::string bad = test::rayfarm_exe() + " study " + scene + " -o " + dir +
                          " --reference-spp 10 > /dev/null 2> " + dir + ".bad";
  CHECK(std::system(bad.c_str()) != 0);
  std::ifstream bad_err(dir + ".bad");
  const std::string message((std::istreambuf_iterator<char>(bad_err)), std::istreambuf_iterator<char>());
  CHECK(message.find("--reference-spp") != std::string::npos);
}

TEST_CASE("study: `rayfarm study` prints its progress escaped, as rayfarm's errors are") {
  // Each line names the scene's file, and may quote why a cached reference is
  // unreadable: an ESC in either reached the terminal as it was.
  const TempDir tmp("exe-escaped");
  std::filesystem::create_directories(tmp.path);
  const std::string scene = tmp.path + "/a\x1b[2Jb.nff";
  std::filesystem::copy_file(test::spd_data("balls-1"), scene);
  const std::string cmd = test::rayfarm_exe() + " study '" + scene + "' -o " + tmp.path + "/out" +
                          " --size 8 --reference-spp 16 --reference-depth 4 --base-spp 1 --base-depth 2"
                          " --spp 1 --depths --adaptive-spp --cutoffs --no-robust --threads 2 --min-time 0"
                          " --no-plots > /dev/null 2> " + tmp.path + "/err";
  REQUIRE(std::system(cmd.c_str()) == 0);
  const std::string progress = read_text(tmp.path + "/err");
  CHECK(progress.find("study: a\\x1b[2Jb [1/") != std::string::npos);
  CHECK(progress.find('\x1b') == std::string::npos);
}

TEST_CASE("study: a folder that cannot be written fails the study before the reference is rendered") {
  const TempDir tmp("unwritable");
  std::filesystem::create_directories(tmp.path);
  const std::string file = tmp.path + "/a-file";
  std::ofstream(file) << "not a folder\n";
  const std::string study = test::rayfarm_exe() + " study " + test::spd_data("balls-1") +
                            " --size 8 --reference-spp 16 --min-time 0 --no-plots ";
  const struct {
    std::string options, folder;
  } cases[] = {{" -o " + file + "/out", file + "/out"},
               {" -o " + tmp.path + "/out --reference-cache " + file, file}};
  for (const auto& c : cases) {
    CAPTURE(c.options);
    const std::string cmd = study + c.options + " > /dev/null 2> " + tmp.path + ".err";
    CHECK(std::system(cmd.c_str()) != 0);
    const std::string message = read_text(tmp.path + ".err");
    CHECK(message.find(c.folder + ": cannot create folder") != std::string::npos);
    CHECK(message.find("reference 16 spp") == std::string::npos);  // no render started
  }
}

TEST_CASE("study: a --plot-script that does not exist is refused before the reference is rendered") {
  const TempDir tmp("plot-script");
  const std::string missing = tmp.path + "/no-plot.py";
  const test::CommandResult run = test::run_command(test::rayfarm_exe() + " study " + test::spd_data("balls-1") +
                                                    " -o " + tmp.path + "/out --size 8 --reference-spp 16"
                                                    " --min-time 0 --plot-script " + missing);
  CHECK(run.exit_code != 0);
  CHECK(run.output.find("--plot-script") != std::string::npos);
  CHECK(run.output.find(missing) != std::string::npos);
  CHECK(run.output.find("reference 16 spp") == std::string::npos);  // no render started
}

}  // namespace rayfarm
