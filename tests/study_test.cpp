// The accuracy study: image metrics, the equal-time interpolation, and a tiny
// end-to-end study (library and `rayfarm study`) whose CSV must have the
// documented shape and whose PSNR must grow with the sample count.
#include <doctest/doctest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "study/image_metrics.h"
#include "study/plot_script.h"
#include "study/quality_study.h"
#include "spd/generators.h"
#include "study/study_report.h"
#include "tests/test_paths.h"
#include "tracer/error.h"
#include "tracer/nff_reader.h"

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

// Haines' sphereflake at `size`, from the repository's own generator.
std::string balls_nff(int size) {
  std::ostringstream text;
  spd::generate("balls", size, text);
  return text.str();
}

StudyOptions tiny_options(const std::string& out_dir) {
  StudyOptions o;
  o.scene_name = "balls-2";
  o.out_dir = out_dir;
  o.size = 16;
  o.reference_spp = 256;
  o.spp_list = {1, 4, 16, 64};
  o.depth_list = {1, 2, 3};
  o.depth_spp = 4;
  o.adaptive_spp = {16};
  o.adaptive_thresholds = {0.2, 0.05};
  o.cutoffs = {0.1, 0.01};
  o.cutoff_spp = 16;
  o.robust_spp = 4;
  o.threads = 2;
  return o;
}

// A fresh directory under the system temp dir, removed again with its
// side files (dir.out, dir.err, ...) when the test ends.
struct TempDir {
  std::string path;
  explicit TempDir(const std::string& name)
      : path((std::filesystem::temp_directory_path() / ("rayfarm_study_test_" + name)).string()) {
    clean();
  }
  ~TempDir() { clean(); }
  void clean() const {
    std::error_code ec;
    std::filesystem::remove_all(path, ec);
    for (const char* ext : {".out", ".err", ".bad", ".nff"}) std::filesystem::remove(path + ext, ec);
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
}

TEST_CASE("study: a tiny study writes a CSV of the documented shape and PSNR grows with spp") {
  const Scene scene = parse_nff(balls_nff(2), "balls-2.nff");
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
    CHECK(files.plots.files == std::vector<std::string>{"error_vs_time.png", "pareto.png", "depth.png"});
    for (const std::string& png : files.plots.files) CHECK(std::filesystem::file_size(o.out_dir + "/" + png) > 1000);
  }
  const auto rows = read_csv(files.csv);
  const size_t columns = study_csv_columns().size();
  // Header, reference, 4 spp, 3 depths, 2 adaptive, 2 cutoffs, 2 robust.
  REQUIRE(rows.size() == 1 + 1 + 4 + 3 + 2 + 2 + 2);
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
  // The deepest depth row is its own baseline; adaptive never traces more eye
  // rays than uniform at its spp.
  CHECK(std::isinf(rows_of(result, "depth").back()->diff.psnr));
  for (const StudyRow* row : rows_of(result, "adaptive")) CHECK(row->rays.eye <= 16u * 16 * 16);
  // A cutoff only removes rays: never more than the full tree at its spp.
  for (const StudyRow* row : rows_of(result, "cutoff")) CHECK(row->rays.total() <= spp[2]->rays.total());
  for (const StudyRow& row : result.rows) CHECK(row.non_finite == 0);
  std::ifstream md(files.markdown);
  const std::string text((std::istreambuf_iterator<char>(md)), std::istreambuf_iterator<char>());
  CHECK(text.find("## Samples per pixel") != std::string::npos);
  CHECK(text.find("## Adaptive supersampling") != std::string::npos);
  CHECK(text.find("## Ray-tree pruning (cutoff)") != std::string::npos);
}

TEST_CASE("study: `rayfarm study` writes study.csv and study.md") {
  const TempDir tmp("exe");
  const std::string& dir = tmp.path;
  const std::string scene = dir + ".nff";
  std::ofstream(scene) << balls_nff(1);
  const std::string cmd = test::rayfarm_exe() + " study " + scene + " -o " + dir +
                          " --size 8 --reference-spp 16 --spp 1 4 --depths 1 2 --depth-spp 1"
                          " --adaptive-spp 9 --contrast 0.1 --cutoffs 0.01 --cutoff-spp 1 --robust-spp 1 --threads 2"
                          " --no-plots"
                          " > " + dir + ".out 2> " + dir + ".err";
  REQUIRE(std::system(cmd.c_str()) == 0);
  const auto rows = read_csv(dir + "/study.csv");
  CHECK(rows.size() == 1 + 1 + 2 + 2 + 1 + 1 + 2);
  CHECK(std::filesystem::exists(dir + "/study.md"));
  std::ifstream err(dir + ".err");
  const std::string progress((std::istreambuf_iterator<char>(err)), std::istreambuf_iterator<char>());
  CHECK(progress.find("study: [1/9] reference") != std::string::npos);
  // A bad option is an error naming it, not a crash.
  const std::string bad = test::rayfarm_exe() + " study " + scene + " -o " + dir +
                          " --reference-spp 10 > /dev/null 2> " + dir + ".bad";
  CHECK(std::system(bad.c_str()) != 0);
  std::ifstream bad_err(dir + ".bad");
  const std::string message((std::istreambuf_iterator<char>(bad_err)), std::istreambuf_iterator<char>());
  CHECK(message.find("--reference-spp") != std::string::npos);
}

}  // namespace rayfarm
