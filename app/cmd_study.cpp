// `rayfarm study SCENE [-o DIR] [--size W] [--reference-spp N] ...`: the
// accuracy-vs-time study of one NFF scene. Parses options and wires the study
// library; progress goes to stderr, the output paths to stdout.
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>
#include <type_traits>

#include "app/commands.h"
#include "study/quality_study.h"
#include "study/study_report.h"
#include "tracer/interrupt_cleanup.h"
#include "tracer/log_text.h"
#include "tracer/nff_reader.h"
#include "tracer/output_file.h"

namespace rayfarm::cmd {

namespace {

struct StudyCommand {
  std::string scene_path;
  StudyOptions options;
  bool no_plots = false;
  std::string plot_script;
};

void run(const StudyCommand& cmd) {
  StudyOptions options = cmd.options;
  const std::string stem = std::filesystem::path(cmd.scene_path).stem().string();
  options.scene_name = stem;
  options.scene_file = cmd.scene_path;
  if (options.out_dir.empty()) options.out_dir = "out/study-" + stem;
  validate(options);
  // A study runs for minutes and writes many files: Ctrl-C leaves no temporary.
  remove_temporaries_on_interrupt();

  const Scene scene = read_nff_file(cmd.scene_path);
  for (const std::string& w : scene.warnings) std::fprintf(stderr, "rayfarm: warning: %s\n", w.c_str());
  // Both are written only once the reference is rendered, which can take an
  // hour: a folder that cannot be written must fail the study now.
  check_output_folder(options.out_dir);
  if (!options.reference_cache.empty()) check_output_folder(options.reference_cache);
  // Escaped as rayfarm's errors are: a line names the scene's file and may
  // quote why a cached reference is unreadable, its own text in part.
  const StudyResult result = run_study(scene, options, [](const std::string& line) {
    std::fprintf(stderr, "%s\n", escape_control_characters(line).c_str());
  });
  const StudyFiles files = write_study(result, options, !cmd.no_plots, cmd.plot_script);
  std::fprintf(stderr, "study: %s\n", files.plots.note.c_str());
  std::printf("%s\n%s\n", files.csv.c_str(), files.markdown.c_str());
  for (const std::string& png : files.plots.files) {
    std::printf("%s\n", (std::filesystem::path(options.out_dir) / png).string().c_str());
  }
}

}  // namespace

void add_study(CLI::App& app) {
  auto cmd = std::make_shared<StudyCommand>();
  cmd->options.out_dir.clear();  // default depends on the scene name
  StudyOptions& o = cmd->options;
  CLI::App* sub = app.add_subcommand(
      "study",
      "accuracy against time: spp, depth, adaptive, cutoff and robust-BVH sweeps against a reference, with Pareto fronts");
  sub->add_option("scene", cmd->scene_path, "NFF scene file")->required();
  sub->add_option("-o,--output", o.out_dir, "output directory (default out/study-SCENE)");
  sub->add_option("--size", o.size, "image width in pixels (height keeps the aspect)")
      ->capture_default_str();
  sub->add_option("--reference-spp", o.reference_spp, "samples per pixel of the reference (a square)")
      ->capture_default_str();
  sub->add_option("--reference-depth", o.reference_depth, "max depth of the reference")->capture_default_str();
  sub->add_option("--reference-cache", o.reference_cache,
                  "directory of cached references: reused when present, written when rendered");
  sub->add_option("--base-spp", o.base_spp, "spp every sweep but spp and adaptive keeps (SPD: 16)")
      ->capture_default_str();
  sub->add_option("--base-depth", o.base_depth, "max depth every sweep but depth keeps (SPD: 5)")
      ->capture_default_str();
  // A sweep list may be given empty ("--depths" alone) to leave that knob out.
  const auto sweep = [sub](const char* name, auto& list, const char* help) {
    using T = typename std::decay_t<decltype(list)>::value_type;
    auto* option = sub->add_option(
        name,
        [&list](const CLI::results_t& values) {
          list.clear();
          for (const std::string& v : values) {
            if (v.empty() || v == "none") continue;  // "none", or an option given without values
            T x{};
            if (!CLI::detail::lexical_cast(v, x)) return false;
            list.push_back(x);
          }
          return true;
        },
        std::string(help) + " (default " + CLI::detail::to_string(list) + "; none = leave the knob out)");
    option->type_size(1)->expected(0, CLI::detail::expected_max_vector_size)->allow_extra_args();
    option->type_name(std::is_integral_v<T> ? "INT" : "FLOAT");
  };
  sweep("--spp", o.spp_list, "uniform spp values to sweep");
  sweep("--depths", o.depth_list, "max depths to sweep");
  sweep("--adaptive-spp", o.adaptive_spp, "full-grid spp of the adaptive sweep");
  sweep("--contrast", o.adaptive_thresholds, "adaptive contrast thresholds");
  sweep("--cutoffs", o.cutoffs, "ray-tree pruning cutoffs to sweep (0 = full tree)");
  sub->add_option("--cutoff-depth", o.cutoff_depth, "max depth of the cutoff sweep")
      ->capture_default_str()
      ->check(CLI::Range(1, 64));
  sub->add_option("--preset", o.presets, "several knobs at once, e.g. spp=64,depth=8,adaptive=0.05 (repeatable)");
  sub->add_flag_callback("--no-robust", [cmd] { cmd->options.robust = false; }, "skip the robust-BVH on/off pair");
  sub->add_option("--threads", o.threads, "render threads (0 = all)")->capture_default_str()->check(CLI::Range(0, 4096));
  sub->add_option("--repeats", o.repeats, "timed runs per setting at least; the fastest counts")
      ->capture_default_str();
  sub->add_option("--min-time", o.min_timed_seconds, "more runs (up to 10) until a setting's runs add up to this")
      ->capture_default_str();
  sub->add_option("--seed", o.seed, "sampler seed")->capture_default_str();
  sub->add_flag("--no-plots", cmd->no_plots, "skip scripts/plot_study.py");
  // Checked up front: a path given but missing was only found out after the
  // whole study, and then reported as if none had been given.
  sub->add_option("--plot-script", cmd->plot_script, "path of plot_study.py (default: search)")
      ->check(CLI::ExistingFile);
  sub->callback([cmd] { run(*cmd); });
}

}  // namespace rayfarm::cmd
