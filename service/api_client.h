// ApiClient: the client side of the service's HTTP API (docs/api.md), used by
// `rayfarm submit | status | cancel | fetch`. Errors carry the server's reason;
// an unreachable broker (or a reverse proxy's 502-504 in front of it) is a
// BrokerUnreachable, so a waiting client can tell "try again later" (a
// restart) from "this will never work" (a bad request).
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <stdexcept>
#include <string>

#include <nlohmann/json.hpp>

#include "service/submission.h"
#include "tracer/image_io.h"

namespace rayfarm {

struct BrokerUnreachable : std::runtime_error {
  using std::runtime_error::runtime_error;
};
// The request went out and no answer came back (the connection closed or
// reset, or the answer's wait ran out): it may or may not have been carried out.
struct AnswerLost : BrokerUnreachable {
  using BrokerUnreachable::BrokerUnreachable;
};
// The answer's wait ran out: the broker had its time, so a submission is sent
// again at once, not after the pause a restarting broker is given.
struct AnswerTimedOut : AnswerLost {
  using AnswerLost::AnswerLost;
};
// The server refused the request; `status` is the HTTP status.
struct ApiError : std::runtime_error {
  ApiError(int status, const std::string& what) : std::runtime_error(what), status(status) {}
  int status;
};

// The broker URL from --broker, else $RAYFARM_BROKER, else
// http://127.0.0.1:8080, and which of them it is, to name in messages.
struct BrokerUrl {
  std::string url;
  std::string source;  // "--broker", "$RAYFARM_BROKER" or "the default broker URL"
};
BrokerUrl broker_url(const std::string& option);

// How a submission is sent again when its answer is lost (AnswerLost): with
// the same Idempotency-Key (docs/api.md), the service answers the job the
// first one made, if it did. Never after an answer, whatever its status.
struct SubmitRetry {
  std::string key;  // "" sends none, and then a lost answer is not retried
  int attempts = 4;  // in all, the first included
  // Before the second attempt after a connection closed unanswered, doubled
  // before each next; none after a wait that ran out (AnswerTimedOut).
  std::chrono::milliseconds backoff{1000};
  std::function<void(const std::string&)> notice;  // hears each retry ({} = silent)
};

// A fresh random Idempotency-Key, "rayfarm-" and 32 hex digits.
std::string random_idempotency_key();

class ApiClient {
 public:
  // `token`: bearer token, "" for none. `url_source` names where a URL that
  // cannot be used came from.
  ApiClient(std::string url, std::string token = "", const std::string& url_source = "--broker");
  ~ApiClient();
  ApiClient(ApiClient&&) noexcept;

  // How long each request waits for the broker's answer once connected
  // (`--timeout`), for every call, in place of the defaults: kQuickAnswer for
  // a status, a list or a cancel, kSlowAnswer for a submission or a frame.
  void set_answer_timeout(std::chrono::seconds timeout);
  // A status, a list or a cancel is answered at once, so a broker silent for
  // seconds is stopped (SIGSTOP), hung or swamped; a submission is answered
  // once every scene is parsed and checked, and a frame's first byte comes
  // once its file is read whole: for the largest, minutes.
  static constexpr std::chrono::seconds kQuickAnswer{10};
  static constexpr std::chrono::seconds kSlowAnswer{300};
  // Hears, while a request waits long for its answer (service/wait_notice.h:
  // from 5 s, or half its wait when that is shorter, then at growing
  // intervals), what it waits for, where, for how long so far and until when;
  // from a thread of its own. None set: nothing is said.
  void set_notice(std::function<void(const std::string&)> notice);

  uint64_t submit(const Submission& submission, const SubmitRetry& retry = {});
  nlohmann::json status(uint64_t job);
  nlohmann::json list();
  nlohmann::json cancel(uint64_t job);
  // Frame `frame` (1-based) of a finished job.
  RgbImage frame(uint64_t job, uint32_t frame);

  // Polls the job until it has finished, riding out a broker that is
  // unreachable (restarting) for up to `patience` at a time. Returns its last
  // status. `notice`, if given, hears when the broker stops answering (why,
  // and for how long it will be waited for), while it stays so at growing
  // intervals, and when it answers again.
  nlohmann::json wait(uint64_t job, std::chrono::seconds patience,
                      const std::function<void(const std::string&)>& notice = {});

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// The job id typed as JOB to `rayfarm status | cancel | fetch`, spelled as
// the API's paths spell it (status/route_table.h): digits without leading
// zeros, at most 19. "007" was read as job 7 while /api/jobs/007 is no path,
// so the client and the API disagreed on what names a job. InputError
// "JOB: expected ..., found '007'" for any other spelling.
uint64_t parse_job_id(const std::string& text);

// Output name of frame `frame` (1-based) of `frames`: OUT itself for one frame,
// else the frame number before the extension, "out.png" -> "out-0003.png".
std::string frame_output_path(const std::string& output, uint32_t frame, uint32_t frames);

}  // namespace rayfarm
