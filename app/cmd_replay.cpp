// `rayfarm replay`: predicts how the farm would do on a lab of machines (the
// paper's 46 SSCs or its 80-machine mixed lab) by simulating the broker's
// dispatch over per-row costs. Parses options, runs replay/replay_job.h,
// prints the report and draws scripts/plot_replay.py's speedup plot.
#include <charconv>
#include <cstdio>
#include <filesystem>
#include <optional>
#include <string_view>
#include <utility>
#include <vector>
#include <unistd.h>

#include "app/commands.h"
#include "app/finite_number.h"
#include "app/image_options.h"
#include "broker/child_process.h"
#include "tracer/text_file.h"
#include "replay/replay_job.h"
#include "replay/row_costs.h"
#include "replay/validation.h"
#include "study/plot_script.h"
#include "tracer/error.h"
#include "tracer/output_file.h"
#include "tracer/executable_path.h"

namespace rayfarm::cmd {
namespace {

namespace fs = std::filesystem;

struct ReplayCli {
  ReplayJob job;
  std::string size, speed_from = "weight", plot_script, policy = "adaptive";
  double latency_ms = 1;
  std::optional<double> stagger_ms;
  bool no_plots = false;
  bool validate = false;
  bool declare_speed = false;
  std::vector<double> throttles{1, 2, 3};
  // Options of one mode only: given in the other they would do nothing.
  std::vector<const CLI::Option*> lab_only, validate_only;
  std::vector<const CLI::Option*> measuring_only;  // they set how --scene is measured
};

// One side of --size's WxH: digits only. sscanf's %d took " 4" and "+4", and
// a side past int's range came out as another number ("99999999999" as
// 1215752191); the renderer's own upper bounds are checked later, with its message.
std::optional<int> size_side(std::string_view text) {
  int value = 0;
  if (text.empty() || text[0] < '0' || text[0] > '9') return std::nullopt;
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (error != std::errc{} || end != text.data() + text.size()) return std::nullopt;
  return value;
}

void parse_size(const std::string& text, ReplayJob& job) {
  const size_t x = text.find_first_of("xX");
  const std::optional<int> w = x == std::string::npos ? std::nullopt : size_side(std::string_view(text).substr(0, x));
  const std::optional<int> h = w ? size_side(std::string_view(text).substr(x + 1)) : std::nullopt;
  if (!h) throw InputError("--size: expected WxH (e.g. 128x128), found \"" + text + "\"");
  // Of the right shape, "0x0" was told it was not.
  if (*w < 1 || *h < 1) throw InputError("--size " + text + ": width and height must be at least 1");
  job.width = *w;
  job.height = *h;
}

std::string find_replay_plot_script(const std::string& explicit_path) {
  if (!explicit_path.empty()) return fs::exists(explicit_path) ? explicit_path : "";
  std::error_code ec;
  std::vector<fs::path> candidates{fs::current_path() / "scripts" / "plot_replay.py"};
  if (const std::string exe = executable_path(); !exe.empty())
    candidates.push_back(fs::path(exe).parent_path().parent_path() / "scripts" / "plot_replay.py");
  for (const fs::path& p : candidates)
    if (fs::exists(p, ec)) return p.string();
  return "";
}

// Progress on stderr: a rewritten line on a terminal, every 10% otherwise.
ReplayProgress stderr_progress() {
  const bool tty = isatty(STDERR_FILENO);
  return [tty, last = std::string(), last_tenth = -1](const std::string& what, int done, int total) mutable {
    const int tenth = total > 0 ? done * 10 / total : 10;
    if (what != last) last_tenth = -1, last = what;
    if (tty) {
      std::fprintf(stderr, "\rreplay: %s %d/%d%s", what.c_str(), done, total, done == total ? "\n" : "");
    } else if (tenth != last_tenth) {
      std::fprintf(stderr, "replay: %s %d/%d\n", what.c_str(), done, total);
    }
    last_tenth = tenth;
  };
}

void refuse_other_mode_options(const ReplayCli& cli) {
  for (const CLI::Option* o : cli.validate ? cli.lab_only : cli.validate_only) {
    if (o->count() == 0) continue;
    if (cli.validate)
      throw InputError(o->get_name() + " does not apply to --validate (a real farm on this machine: one 1-thread "
                                       "worker per --throttles entry)");
    throw InputError(o->get_name() + " applies only with --validate");
  }
  if (cli.job.costs_path.empty()) return;
  for (const CLI::Option* o : cli.measuring_only)
    if (o->count() > 0)
      throw InputError(o->get_name() + " sets how --scene is measured; --costs brings row costs already measured");
}

// `--costs out/costs.json -o out` replaced the measured profile with the
// resampled, rescaled one, and a second run rescaled that again; an input
// among the outputs is refused instead.
void refuse_inputs_among_outputs(const ReplayJob& j, bool validate) {
  std::vector<std::pair<std::string, std::string>> files{
      {"--costs", j.costs_path}, {"--scene", j.scene_path}, {"--lab", j.lab_path}};
  const std::vector<std::string> outputs =
      validate ? std::vector<std::string>{"costs.json", "validation.md", "record.json"}
               : std::vector<std::string>{"costs.json", "replay.md", "machines.csv", "replay.json", "tasks.csv",
                                          "sweep.csv"};
  // The folder itself too: `-o` naming an input file said "--costs FILE:
  // cannot create folder", of the option that was right.
  files.emplace_back("-o", j.out_dir);
  for (const std::string& name : outputs) files.emplace_back("-o", (fs::path(j.out_dir) / name).string());
  check_distinct_files(files);
}

// --validate: a real throttled farm on this machine vs its replay.
void run_validate(ReplayCli& cli) {
  const ReplayJob& j = cli.job;
  if (j.scene_path.empty()) throw InputError("--validate needs --scene FILE");
  ValidationSpec spec;
  spec.scene_path = j.scene_path;
  if (j.width) spec.width = *j.width;
  if (j.height) spec.height = *j.height;
  spec.spp = j.spp;
  spec.throttles = cli.throttles;
  spec.policy = j.sim.policy;
  spec.declare_speed = cli.declare_speed;
  spec.base_task_rows = j.sim.base_task_rows;
  if (j.credit) spec.credit = *j.credit;
  spec.repeats = j.repeats;
  spec.latency_s = cli.latency_ms / 1e3;
  spec.executable = self_executable();
  std::fprintf(stderr, "replay: validating on %s (%zu throttled workers)\n", spec.scene_path.c_str(), spec.throttles.size());
  const ValidationResult v = run_validation(spec);
  std::fputs(v.markdown.c_str(), stdout);
  if (j.out_dir.empty()) return;
  std::error_code ec;
  fs::create_directories(j.out_dir, ec);
  if (ec) throw InputError(j.out_dir + ": cannot create directory: " + ec.message());
  write_text_file((fs::path(j.out_dir) / "validation.md").string(), v.markdown);
  write_text_file((fs::path(j.out_dir) / "record.json").string(), v.record.dump(1) + "\n");
  write_text_file((fs::path(j.out_dir) / "costs.json").string(), row_costs_json(v.measured).dump(1) + "\n");
  std::fprintf(stderr, "replay: wrote %s/validation.md, record.json and costs.json (the measured row costs)\n",
               j.out_dir.c_str());
}

void run(ReplayCli& cli) {
  if (!cli.size.empty()) parse_size(cli.size, cli.job);
  cli.job.sim.policy = parse_policy(cli.policy, "--policy");
  refuse_other_mode_options(cli);
  // Written only after the row costs are measured or a real farm has run.
  if (!cli.job.out_dir.empty()) {
    refuse_inputs_among_outputs(cli.job, cli.validate);
    check_output_folder(cli.job.out_dir);
  }
  if (cli.validate) return run_validate(cli);
  if (cli.speed_from != "weight" && cli.speed_from != "throttle")
    throw InputError("--speed-from: expected weight or throttle, found \"" + cli.speed_from + "\"");
  cli.job.speed_from = cli.speed_from == "weight" ? SpeedFrom::weight : SpeedFrom::throttle;
  cli.job.sim.latency_s = cli.latency_ms / 1e3;
  if (cli.stagger_ms) cli.job.stagger_s = *cli.stagger_ms / 1e3;
  const ReplayOutput out = run_replay(cli.job, stderr_progress());
  std::fputs(out.markdown.c_str(), stdout);
  for (const std::string& f : out.files) std::fprintf(stderr, "replay: wrote %s\n", f.c_str());
  if (cli.job.out_dir.empty() || out.points.empty() || cli.no_plots) return;
  const std::string script = find_replay_plot_script(cli.plot_script);
  if (script.empty()) {
    std::fprintf(stderr, "replay: no plot: scripts/plot_replay.py not found (run from the source tree or pass --plot-script)\n");
    return;
  }
  const PlotOutcome plots = run_plot_script(script, (fs::path(cli.job.out_dir) / "sweep.csv").string(), cli.job.out_dir);
  for (const std::string& png : plots.files) std::fprintf(stderr, "replay: wrote %s\n", (fs::path(cli.job.out_dir) / png).c_str());
  if (plots.files.empty()) std::fprintf(stderr, "replay: %s\n", plots.note.c_str());
}

}  // namespace

void add_replay(CLI::App& app) {
  auto* sub = app.add_subcommand("replay", "predict farm speedup on a lab of machines by simulating the broker's dispatch");
  auto cli = std::make_shared<ReplayCli>();
  ReplayJob& j = cli->job;
  auto* costs = sub->add_option("--costs", j.costs_path, "row costs: a costs.json from an earlier replay, or a job record");
  auto* scene = sub->add_option("--scene", j.scene_path, "measure row costs by rendering each row of this NFF scene once");
  costs->excludes(scene);
  sub->add_option("--size", cli->size, "measurement image size WxH (default: the scene's)");
  sub->add_option("--spp", j.spp, "measurement samples per pixel (a perfect square)")
      ->capture_default_str()
      ->check(CLI::Range(1, kMaxSpp))
      ->check(square_spp());
  sub->add_option("--threads", j.threads, "measurement threads (1 = per-core costs)")->capture_default_str()->check(CLI::Range(0, 4096));
  sub->add_option("--repeats", j.repeats, "renders per row when measuring; the fastest counts")
      ->capture_default_str()
      ->check(CLI::Range(1, 100));
  sub->add_option("--paper", j.paper, "scale to the paper: tetra|balls|mount|rings|gears (512 rows, Table 2 time, init, start-up stagger)");
  sub->add_option("--rows", j.rows, "resample the profile to this many rows")->check(CLI::Range(1, 65536));
  sub->add_option("--sequential-s", j.sequential_s, "scale so the sequential run (with init) takes this long")
      ->check(finite_number(0, kMaxReplaySeconds));
  sub->add_option("--init-s", j.init_s, "per-machine init (parse + BVH) on a speed-1 machine")
      ->check(finite_number(0, kMaxReplaySeconds));
  sub->add_option("--lab", j.lab_path, "lab file, e.g. configs/labs/paper-lab.json (required unless --validate)");
  sub->add_option("--speed-from", cli->speed_from, "machine speed from 'weight' (SPECfp92 / reference) or 'throttle'")->capture_default_str();
  sub->add_option("--base-rows", j.sim.base_task_rows, "rows per task at the reference weight")->capture_default_str()
      ->check(CLI::Range(1, 65536));
  sub->add_option("--credit", j.credit, "tasks in flight per machine (default: each worker config's; the paper: 1)")
      ->check(CLI::Range(1, 64));
  sub->add_option("--policy", cli->policy, std::string("dispatch policy: ") + kPolicyNames)->capture_default_str();
  sub->add_flag("--prior-frame", j.sim.prior_frame, "adaptive: row costs known from the previous frame (a still scene)");
  sub->add_option("--min-span", j.sim.min_span_pixels, "adaptive: narrowest pixel span the tail rows are cut into (0: whole rows)")
      ->capture_default_str()
      ->check(CLI::Range(0, 65536));
  sub->add_option("--latency-ms", cli->latency_ms, "one-way message latency")->capture_default_str()
      ->check(finite_number(0, kMaxReplaySeconds * 1e3));
  sub->add_option("--stagger-ms", cli->stagger_ms,
                  "delay between machines starting to load the scene (default 0; with --paper the paper's 600)")
      ->check(finite_number(0, kMaxReplaySeconds * 1e3));
  sub->add_flag("--sweep", j.sweep, "also simulate growing subsets (1..N reference machines, 1..all machines)");
  sub->add_option("-o,--output", j.out_dir, "directory for costs.json, replay.md, machines.csv, sweep.csv, speedup.png");
  sub->add_flag("--validate", cli->validate,
                "run a real throttled farm on --scene (one 1-thread worker per --throttles entry) and compare with its replay");
  sub->add_option("--throttles", cli->throttles, "worker throttles for --validate")
      ->capture_default_str()
      ->delimiter(',')
      ->check(finite_number(1, 1000));
  sub->add_flag("--declare-speed", cli->declare_speed,
                "with --validate: workers announce weight = reference / throttle (else all the reference weight)");
  sub->add_flag("--no-plots", cli->no_plots, "skip scripts/plot_replay.py");
  // Checked up front, like study's: not found after the replay and reported as if not given.
  sub->add_option("--plot-script", cli->plot_script, "path of plot_replay.py (default: search)")
      ->check(CLI::ExistingFile);
  for (const char* name : {"--threads", "--paper", "--rows", "--sequential-s", "--init-s", "--lab", "--speed-from",
                           "--prior-frame", "--min-span", "--stagger-ms", "--sweep", "--plot-script"})
    cli->lab_only.push_back(sub->get_option(name));
  for (const char* name : {"--throttles", "--declare-speed"}) cli->validate_only.push_back(sub->get_option(name));
  for (const char* name : {"--size", "--spp", "--threads", "--repeats"}) cli->measuring_only.push_back(sub->get_option(name));
  sub->callback([cli] { run(*cli); });
}

}  // namespace rayfarm::cmd
