// The service's client commands, `rayfarm submit | status | cancel | fetch`:
// each parses its options and makes one or two ApiClient calls
// (service/api_client.h). `submit` prints the job id alone on stdout so a
// script can capture it; everything else a person reads goes to stderr.
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <memory>

#include "app/commands.h"
#include "app/image_options.h"
#include "service/api_client.h"
#include "service/http_api.h"
#include "tracer/error.h"
#include "tracer/interrupt_cleanup.h"
#include "tracer/log_text.h"
#include "tracer/nff_reader.h"
#include "tracer/output_file.h"

namespace rayfarm::cmd {
namespace {

// A job's fields as printed to a terminal: its error can carry a worker's
// message and its scene's name, and an ESC, BEL or CR in them would drive the
// user's terminal (retitle it, clear it, overwrite the line) rather than be read.
std::string terminal_text(const nlohmann::json& s, const char* key) {
  return escape_control_characters(s.at(key).get<std::string>());
}

// The JSON with every character past ASCII written as a \u escape: the same
// JSON, but the C1 controls (U+0080..U+009F, a CSI among them), which the
// dump leaves raw, cannot reach the terminal; C0 ones it escapes anyway.
std::string json_for_terminal(const nlohmann::json& j) { return j.dump(2, ' ', true); }

// What a client says as it goes: to stderr, stdout being for scripts. It may
// quote the broker's (or a proxy's) reason for a busy answer, text from the
// network, so it is escaped as rayfarm's errors and the job's fields are.
void say(const std::string& text) { std::fprintf(stderr, "rayfarm: %s\n", escape_control_characters(text).c_str()); }

struct Connection {
  std::string broker, token_file;
  int timeout = 0;  // seconds; 0: each request's default
};

// Up to a day: a wait longer than that is no wait for an answer.
constexpr int kMaxTimeoutSeconds = 86400;

void add_connection_options(CLI::App* sub, Connection& c) {
  sub->add_option("--broker", c.broker, "service URL (default $RAYFARM_BROKER, else http://127.0.0.1:8080)");
  sub->add_option("--token-file", c.token_file, "bearer token for a service beyond loopback (default $RAYFARM_TOKEN_FILE)")
      ->check(CLI::ExistingFile);
  sub->add_option("--timeout", c.timeout,
                  "seconds to wait for each answer of the broker once connected (default " +
                      std::to_string(ApiClient::kQuickAnswer.count()) + " for a status or a cancel, " +
                      std::to_string(ApiClient::kSlowAnswer.count()) +
                      " for a submission or a frame); a wait past 5 s, or half of it, is said on stderr")
      ->check(CLI::Range(1, kMaxTimeoutSeconds));
}

ApiClient connect(const Connection& c) {
  // The HTTP library sends without MSG_NOSIGNAL: a service that answers 503 at
  // its connection cap and closes while a submit's body is still going out
  // would kill the client by SIGPIPE (exit 141, not a word). Ignored, the send
  // fails and the client says what happened.
  std::signal(SIGPIPE, SIG_IGN);
  std::string token_file = c.token_file;
  if (token_file.empty())
    if (const char* env = std::getenv("RAYFARM_TOKEN_FILE")) token_file = env;
  const BrokerUrl broker = broker_url(c.broker);
  ApiClient api(broker.url, token_file.empty() ? "" : read_token_file(token_file), broker.source);
  if (c.timeout > 0) api.set_answer_timeout(std::chrono::seconds(c.timeout));
  api.set_notice(say);  // a long wait for an answer is said, not sat through in silence
  return api;
}

// Waits (riding out broker restarts of up to 10 minutes) unless told not to,
// then writes every frame: OUT, or OUT-0001.png ... for several frames.
void fetch_frames(ApiClient& api, uint64_t job, const std::string& output, bool wait) {
  const nlohmann::json s = wait ? api.wait(job, std::chrono::minutes(10), say) : api.status(job);
  // Raw in the error: rayfarm's error printer escapes it (run_commands), once.
  const std::string state = s.at("state").get<std::string>();
  // A job still to finish is no failure of it: say how to wait for it.
  const bool unfinished = state == "queued" || state == "running";
  if (state != "done")
    throw std::runtime_error("job " + std::to_string(job) + " is " + state +
                             (s.contains("error") ? ": " + s.at("error").get<std::string>() : std::string()) +
                             (unfinished ? " (add --wait to wait for it and write its frames)" : ""));
  const uint32_t frames = s.at("frames").get<uint32_t>();
  remove_temporaries_on_interrupt();  // no temporary of a frame left by Ctrl-C, as `render` leaves none
  for (uint32_t f = 1; f <= frames; ++f) {
    const RgbImage img = api.frame(job, f);
    const std::string path = frame_output_path(output, f, frames);
    write_image(path, img.width, img.height, img.rgb);
    std::fprintf(stderr, "rayfarm: wrote %s\n", path.c_str());
  }
}

// Before any waiting or download: an image that cannot be written is said at
// once, not after the job has rendered (as `rayfarm render` checks its -o).
void check_output_image(const std::string& output) {
  check_image_path(output);
  check_output_path(output);
}

void print_status_line(const nlohmann::json& s) {
  const auto rows = [&](const char* key) { return static_cast<long long>(s.at(key).get<int64_t>()); };
  const std::string error = s.contains("error") ? "  (" + terminal_text(s, "error") + ")" : "";
  std::printf("%-6s %-9s frames %d/%d  rows %lld/%lld  resumed %lld  re-rendered %lld%s\n",
              std::to_string(s.at("id").get<uint64_t>()).c_str(), terminal_text(s, "state").c_str(),
              s.at("frames_done").get<int>(), s.at("frames").get<int>(), rows("rows_done"), rows("rows_total"),
              rows("resumed_rows"), rows("rerendered_rows"), error.c_str());
}

void add_submit_command(CLI::App& app) {
  struct Options {
    Connection connection;
    std::vector<std::string> scenes;
    Submission submission;
    ImageOptions image;
    std::string output;
    std::string idempotency_key;
    bool wait = false;
  };
  auto o = std::make_shared<Options>();
  auto* sub = app.add_subcommand("submit", "queue a job on a rayfarm service; prints the job id");
  add_connection_options(sub, o->connection);
  RenderOverrides& r = o->submission.overrides;
  sub->add_option("scenes", o->scenes, "NFF scene files: several make one job of frames, rendered in order")
      ->required()->check(CLI::ExistingFile);
  o->image.add_to(sub, r);
  sub->add_option("--priority", o->submission.priority, "higher runs before queued jobs of lower priority")
      ->capture_default_str();
  sub->add_flag("--wait", o->wait, "wait for the job and write its frames to -o");
  sub->add_option("-o,--output", o->output, "with --wait: output image (frames: OUT-0001.png, ...)");
  auto* key_option = sub->add_option("--idempotency-key", o->idempotency_key,
                  "names this submission (1 to 255 printable ASCII characters): a service that already took one "
                  "with the key and the same job answers that job, not a second (default: a fresh random key; "
                  "either way a submission whose answer is lost, the connection closed or --timeout passed, is "
                  "sent again up to 3 times with the key, each said on stderr)");
  sub->callback([o, key_option] {
    // Given empty it is refused, not replaced by a random key the script does not know.
    const std::string key_fault = idempotency_key_fault(o->idempotency_key);
    if (key_option->count() > 0 && !key_fault.empty()) throw InputError("--idempotency-key: " + key_fault);
    if (o->wait && o->output.empty()) throw InputError("submit --wait needs -o OUT");
    if (!o->wait && !o->output.empty())
      throw InputError("submit -o OUT needs --wait (or fetch the job later: rayfarm fetch JOB -o OUT)");
    o->image.apply_size(o->submission.overrides);
    for (const std::string& path : o->scenes) o->submission.scenes.push_back({path, read_nff_text(path)});
    check_scene_names(o->submission);  // the service checks these too; failing here names the local file first
    check_submission(o->submission);
    if (!o->output.empty()) check_output_image(o->output);
    ApiClient api = connect(o->connection);
    SubmitRetry retry;
    retry.key = key_option->count() > 0 ? o->idempotency_key : random_idempotency_key();
    retry.notice = say;
    const uint64_t job = api.submit(o->submission, retry);
    std::printf("%llu\n", static_cast<unsigned long long>(job));
    std::fflush(stdout);
    if (o->wait) fetch_frames(api, job, o->output, true);
  });
}

void add_status_command(CLI::App& app) {
  struct Options {
    Connection connection;
    std::string job;
    bool json = false;
  };
  auto o = std::make_shared<Options>();
  auto* sub = app.add_subcommand("status", "show a job of a rayfarm service, or all jobs");
  add_connection_options(sub, o->connection);
  sub->add_option("job", o->job, "job id (default: all jobs)");
  sub->add_flag("--json", o->json, "print the JSON the service answered");
  sub->callback([o] {
    ApiClient api = connect(o->connection);
    const nlohmann::json s = o->job.empty() ? api.list() : api.status(parse_job_id(o->job));
    if (o->json) {
      std::printf("%s\n", json_for_terminal(s).c_str());
    } else if (s.is_array()) {
      for (const auto& j : s) print_status_line(j);
    } else {
      print_status_line(s);
    }
  });
}

void add_cancel_command(CLI::App& app) {
  auto o = std::make_shared<std::pair<Connection, std::string>>();
  auto* sub = app.add_subcommand("cancel", "cancel a queued or running job");
  add_connection_options(sub, o->first);
  sub->add_option("job", o->second, "job id")->required();
  sub->callback([o] {
    ApiClient api = connect(o->first);
    print_status_line(api.cancel(parse_job_id(o->second)));
  });
}

void add_fetch_command(CLI::App& app) {
  struct Options {
    Connection connection;
    std::string job, output;
    bool wait = false;
  };
  auto o = std::make_shared<Options>();
  auto* sub = app.add_subcommand("fetch", "download a finished job's images");
  add_connection_options(sub, o->connection);
  sub->add_option("job", o->job, "job id")->required();
  sub->add_option("-o,--output", o->output, "output image (frames: OUT-0001.png, ...)")->required();
  sub->add_flag("--wait", o->wait, "wait for the job to finish (also across a broker restart)");
  sub->callback([o] {
    check_output_image(o->output);
    ApiClient api = connect(o->connection);
    fetch_frames(api, parse_job_id(o->job), o->output, o->wait);
  });
}

}  // namespace

void add_client(CLI::App& app) {
  add_submit_command(app);
  add_status_command(app);
  add_cancel_command(app);
  add_fetch_command(app);
}

}  // namespace rayfarm::cmd
