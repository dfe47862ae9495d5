// The HTTP API client; see api_client.h.
#include "service/api_client.h"

#include <httplib.h>

#include <cstdio>
#include <cstdlib>
#include <functional>
#include <optional>
#include <random>
#include <regex>
#include <thread>

#include "service/frame_file.h"
#include "service/job_queue.h"
#include "service/wait_notice.h"
#include "status/route_table.h"
#include "tracer/error.h"
#include "tracer/text_file.h"

namespace rayfarm {

using nlohmann::json;
using Clock = std::chrono::steady_clock;

BrokerUrl broker_url(const std::string& option) {
  if (!option.empty()) return {option, "--broker"};
  if (const char* env = std::getenv("RAYFARM_BROKER"); env && *env) return {env, "$RAYFARM_BROKER"};
  return {"http://127.0.0.1:8080", "the default broker URL"};
}

std::string frame_output_path(const std::string& output, uint32_t frame, uint32_t frames) {
  if (frames <= 1) return output;
  const size_t slash = output.find_last_of('/');
  size_t dot = output.find_last_of('.');
  if (dot == std::string::npos || (slash != std::string::npos && dot < slash)) dot = output.size();
  char number[16];
  std::snprintf(number, sizeof number, "-%04u", frame);
  return output.substr(0, dot) + number + output.substr(dot);
}

std::string random_idempotency_key() {
  std::random_device random;
  char key[48];
  std::snprintf(key, sizeof key, "rayfarm-%08x%08x%08x%08x", random(), random(), random(), random());
  return key;
}

uint64_t parse_job_id(const std::string& text) {
  static const std::regex path_number(kPathNumber);
  if (!std::regex_match(text, path_number)) {
    throw InputError("JOB: expected a job id, digits without leading zeros (7, not 07), at most 19, found '" +
                     quoted_excerpt(text, 40) + "'");
  }
  return std::stoull(text);
}

namespace {

// httplib's client takes [scheme://]host[:port] and nothing else: given more
// (a path, a query, user@, a port past 65535, an upper-case scheme) it does
// not refuse, it fails every request as a connection error, which `fetch
// --wait` would retry for ten minutes. The status page's address, which people
// copy, ends in '/': that slash is dropped, anything else refused.
std::string checked_url(std::string url, const std::string& source) {
  if (!url.empty() && url.back() == '/') url.pop_back();
  const size_t scheme = url.find("://");
  if (url.find('/', scheme == std::string::npos ? 0 : scheme + 3) != std::string::npos)
    throw InputError(source + ": '" + url + "' has a path; expected http://HOST:PORT");
  static const std::regex host_port(R"((?:https?://)?(?:\[[0-9A-Fa-f:.]+\]|[^\s:/?#@\[\]]+)(?::([0-9]{1,5}))?)");
  std::smatch m;
  if (!std::regex_match(url, m, host_port) || (m[1].matched && (std::stoi(m[1]) < 1 || std::stoi(m[1]) > 65535)))
    throw InputError(source + ": '" + url + "' is not http://HOST:PORT (PORT 1..65535)");
  return url;
}

}  // namespace

struct ApiClient::Impl {
  std::string url;
  httplib::Client client;
  std::optional<std::chrono::seconds> answer_timeout;  // set_answer_timeout()'s, for every call
  std::function<void(const std::string&)> notice;       // set_notice()'s

  // How long a call of the kind whose default is `usual` waits for an answer.
  std::chrono::seconds patience(std::chrono::seconds usual) const { return answer_timeout.value_or(usual); }

  Impl(std::string u, const std::string& token, const std::string& source)
      : url(checked_url(std::move(u), source)), client(url) {
    if (!client.is_valid()) throw InputError(source + ": cannot use '" + url + "' (expected http://HOST:PORT)");
    client.set_connection_timeout(std::chrono::seconds(5));
    if (!token.empty()) client.set_bearer_token_auth(token);
  }

  // One request as the client waits for it.
  struct Ask {
    std::string what;  // the command, naming it in errors: "submit", "status", "cancel", "fetch"
    std::string noun;  // naming it in waiting notices: "the submission", "job 7's status"
    // A submission or a cancel: it may still be carried out by a broker that answers late.
    bool changes_state = false;
    std::string then;  // what follows a wait that runs out, said in its notices; "" for nothing
    bool quiet = false;  // its wait is told otherwise (wait()'s own notices)
  };

  // One request, its answer awaited for up to `patience`, told to `notice`
  // while it is long (WaitNotice). `request` gets the progress hook that ends
  // the notices once the answer's body comes: the wait is over, and a long
  // frame download is no silence. The kernel takes the connection even for a
  // stopped broker, which then says nothing: that broker is unreachable, so
  // `fetch --wait` waits it out as it waits out a restart. A request that
  // changes the broker's state may still be carried out by a broker that
  // answers late: the user is told so, and not to send it again blindly.
  std::string exchange(std::chrono::seconds usual_patience,
                       const std::function<httplib::Result(const httplib::Progress&)>& request, const Ask& ask) {
    const std::chrono::seconds limit = patience(usual_patience);
    client.set_read_timeout(limit);
    const auto start = Clock::now();
    std::optional<WaitNotice> waiting;
    if (notice && !ask.quiet)
      waiting.emplace(NoticeSchedule(limit), [this, &ask, limit](std::chrono::milliseconds waited) {
        notice("waiting for the broker at " + url + " to answer " + ask.noun + " (" + seconds_text(waited) +
               " so far; giving up after " + seconds_text(limit) + (ask.then.empty() ? "" : ", then " + ask.then) +
               ")");
      });
    const httplib::Result r = request([&waiting](uint64_t, uint64_t) {
      if (waiting) waiting->stop();
      return true;
    });
    waiting.reset();
    const std::string& what = ask.what;
    const bool changes_state = ask.changes_state;
    if (!r && r.error() == httplib::Error::Read && Clock::now() - start >= limit)
      throw AnswerTimedOut("the broker at " + url + " did not answer within " + std::to_string(limit.count()) +
                           " s (is it stopped or hung? --timeout SECONDS sets the wait)" +
                           (changes_state ? "; the " + what + " may still take effect when it answers: see rayfarm status"
                                          : ""));
    // The request went out and the connection closed unanswered: the broker
    // stopped (a crash, a restart) while serving it. Said as "cannot reach",
    // a submission the broker had already stored looked never sent, and was
    // sent again as a second job.
    if (!r && r.error() == httplib::Error::Read)
      throw AnswerLost("the broker at " + url + " closed the connection before answering (did it stop or " +
                       "restart?)" + (changes_state ? "; the " + what + " may have taken effect: see rayfarm status" : ""));
    // The connection closed while the request was still going out (a broker
    // at its connection limit answers 503 and closes at once): the request
    // was never whole, so nothing of it was carried out.
    if (!r && r.error() == httplib::Error::Write)
      throw BrokerUnreachable("the broker at " + url + " closed the connection while the " + what +
                              " was being sent (busy, or stopping?); nothing was taken: retry later");
    return check(r, what);
  }

  // The body of a 2xx answer; otherwise the server's reason.
  std::string check(const httplib::Result& r, const std::string& what) {
    if (!r) throw BrokerUnreachable("cannot reach the broker at " + url + " (" + httplib::to_string(r.error()) + ")");
    // A reverse proxy in front (docs/deployment.md) answers 502, 503 or 504
    // while the broker behind it restarts; the broker itself answers 503 when
    // it has as many connections or bodies as it takes, with its reason.
    // Either is to be tried again later.
    if (r->status == 502 || r->status == 503 || r->status == 504) {
      const std::optional<std::string> own = reason_of(r->body);
      if (own) throw BrokerUnreachable("the broker at " + url + " is busy (HTTP " + std::to_string(r->status) + "): " + *own);
      throw BrokerUnreachable("the proxy at " + url + " cannot reach the broker (HTTP " + std::to_string(r->status) +
                              ")");
    }
    if (r->status >= 200 && r->status < 300) return r->body;
    // Every refusal of the broker's is JSON: one without a reason is a proxy's
    // (say, its body size limit) or another program's, and its page is no reason.
    const std::string reason = reason_of(r->body).value_or(
        "HTTP " + std::to_string(r->status) + " " + r->reason + " from " + url +
        ", not the broker's own answer (a proxy's, or another program's on that port)");
    throw ApiError(r->status, what + ": " + reason);
  }

  // The reason of the broker's JSON refusal; none for another body.
  static std::optional<std::string> reason_of(const std::string& body) {
    try {
      // As the broker said it: it can name a scene, with control characters in
      // it, which whoever prints the error escapes (rayfarm's error printer does).
      return json::parse(body).at("error").get<std::string>();
    } catch (const std::exception&) {
      return std::nullopt;
    }
  }

  // An answer that is not the API's (another program on that port) is named
  // as such, with the URL, not by the JSON parser's complaint about a key.
  [[noreturn]] void not_the_api(const std::string& path, const std::string& what_came) const {
    throw std::runtime_error(url + path + " answered " + what_came + ": is " + url + " a rayfarm broker?");
  }

  json parse_answer(const std::string& body, const std::string& path) const {
    try {
      return json::parse(body);
    } catch (const json::exception&) {
      not_the_api(path, "something other than JSON");
    }
  }

  json get_json(const std::string& path, const Ask& ask) {
    return parse_answer(
        exchange(kQuickAnswer, [&](const httplib::Progress& progress) { return client.Get(path, progress); }, ask),
        path);
  }
  // The HTTP library's POST has no progress hook; the API's JSON answer is
  // small, and ends the wait as it comes.
  json post_json(const std::string& path, const std::string& body, const Ask& ask, std::chrono::seconds patience,
                 const httplib::Headers& headers = {}) {
    return parse_answer(
        exchange(patience, [&](const httplib::Progress&) { return client.Post(path, headers, body, "application/json"); },
                 ask),
        path);
  }

  // A job's status; `then` and `quiet` as in Ask, for wait()'s polls.
  json status_of(uint64_t job, const std::string& then = "", bool quiet = false) {
    const std::string path = "/api/jobs/" + std::to_string(job);
    return job_status(get_json(path, {"status", "job " + std::to_string(job) + "'s status", false, then, quiet}), path);
  }

  // The submission, sent again while its answer is lost and attempts remain.
  json post_submission(const std::string& body, const SubmitRetry& retry) {
    httplib::Headers headers;
    if (!retry.key.empty()) headers.emplace("Idempotency-Key", retry.key);
    auto wait = retry.backoff;
    for (int attempt = 1;; ++attempt) {
      try {
        // Without a key a lost answer is not retried: nothing follows.
        const bool last = retry.key.empty() || attempt >= retry.attempts;
        const Ask ask{"submit",
                      attempt == 1 ? "the submission"
                                   : "the submission, sent again (attempt " + std::to_string(attempt) + " of " +
                                         std::to_string(retry.attempts) + ")",
                      true, last ? "" : "sending it again", false};
        return post_json("/api/jobs", body, ask, kSlowAnswer, headers);
      } catch (const AnswerLost& e) {
        if (retry.key.empty()) throw;
        if (attempt >= retry.attempts)
          throw AnswerLost(std::string(e.what()) + " (sent " + std::to_string(attempt) +
                           " times; to try again without a second job: --idempotency-key " + retry.key + ")");
        // A broker that took the whole wait is not given more of it: a pause
        // on top only lengthened a submit to a hung broker.
        const bool waited = dynamic_cast<const AnswerTimedOut*>(&e) != nullptr;
        if (retry.notice)
          retry.notice(std::string(e.what()) + "; sending it again " + (waited ? "now" : "in " + seconds_text(wait)) +
                       " with the same Idempotency-Key, which makes no second job (attempt " +
                       std::to_string(attempt + 1) + " of " + std::to_string(retry.attempts) + ")");
        if (waited) continue;
        std::this_thread::sleep_for(wait);
        wait *= 2;
      }
    }
  }

  static std::string seconds_text(std::chrono::milliseconds ms) {
    char text[32];
    std::snprintf(text, sizeof text, "%g s", static_cast<double>(ms.count()) / 1000);
    return text;
  }

  // A job status with every key docs/api.md gives it that the clients read.
  const json& job_status(const json& s, const std::string& path) const {
    bool whole = s.is_object() && s.contains("state") && s["state"].is_string();
    for (const char* count :
         {"id", "frames", "frames_done", "rows_done", "rows_total", "resumed_rows", "rerendered_rows"})
      whole = whole && s.contains(count) && s[count].is_number_unsigned();
    whole = whole && (!s.contains("error") || s["error"].is_string());  // printed as text
    if (!whole) not_the_api(path, "JSON that is no job status");
    return s;
  }
};

ApiClient::ApiClient(std::string url, std::string token, const std::string& url_source)
    : impl_(std::make_unique<Impl>(std::move(url), token, url_source)) {}
ApiClient::~ApiClient() = default;
ApiClient::ApiClient(ApiClient&&) noexcept = default;

void ApiClient::set_answer_timeout(std::chrono::seconds timeout) { impl_->answer_timeout = timeout; }
void ApiClient::set_notice(std::function<void(const std::string&)> notice) { impl_->notice = std::move(notice); }

uint64_t ApiClient::submit(const Submission& s, const SubmitRetry& retry) {
  // JSON carries UTF-8 only: a file name or an NFF comment in another encoding
  // (a Latin-1 "scène") goes with U+FFFD in place of its odd bytes. Comments
  // are all NFF lets such bytes into, and it reads nothing from them, so the
  // service renders what `rayfarm render` does from the file itself.
  const std::string body = submission_json(s).dump(-1, ' ', false, json::error_handler_t::replace);
  const json answer = impl_->post_submission(body, retry);
  const uint64_t id = impl_->job_status(answer, "/api/jobs").at("id").get<uint64_t>();
  if (answer.value("earlier_submission", false) && retry.notice)
    retry.notice("the broker already held this submission (Idempotency-Key " + retry.key + "): job " +
                 std::to_string(id) + ", not a second one");
  return id;
}

json ApiClient::status(uint64_t job) { return impl_->status_of(job); }
json ApiClient::list() {
  json jobs = impl_->get_json("/api/jobs", {"status", "the list of jobs", false, "", false});
  if (!jobs.is_array()) impl_->not_the_api("/api/jobs", "JSON that is no list of jobs");
  for (const json& s : jobs) impl_->job_status(s, "/api/jobs");
  return jobs;
}
json ApiClient::cancel(uint64_t job) {
  const std::string path = "/api/jobs/" + std::to_string(job) + "/cancel";
  return impl_->job_status(
      impl_->post_json(path, "", {"cancel", "the cancel of job " + std::to_string(job), true, "", false}, kQuickAnswer), path);
}

RgbImage ApiClient::frame(uint64_t job, uint32_t frame) {
  const std::string path = "/api/jobs/" + std::to_string(job) + "/frames/" + std::to_string(frame);
  const std::string bytes = impl_->exchange(
      kSlowAnswer, [&](const httplib::Progress& progress) { return impl_->client.Get(path, progress); },
      {"fetch", "the request for frame " + std::to_string(frame) + " of job " + std::to_string(job), false, "", false});
  return decode_frame(bytes, impl_->url + path);
}

json ApiClient::wait(uint64_t job, std::chrono::seconds patience,
                     const std::function<void(const std::string&)>& notice) {
  auto unreachable_since = Clock::time_point{};
  std::optional<NoticeSchedule> reminders;  // while unreachable
  const auto tell = [&notice](const std::string& text) {
    if (notice) notice(text);
  };
  const std::string url = impl_->url;
  const std::string then = "waiting up to " + std::to_string(patience.count()) + " s for it";
  while (true) {
    try {
      // While the broker is unreachable this loop tells the wait at its own
      // growing intervals: a poll's notices would start over at every poll.
      json s = impl_->status_of(job, then, reminders.has_value());
      if (unreachable_since != Clock::time_point{}) tell("the broker at " + url + " answers again");
      unreachable_since = {};
      reminders.reset();
      if (is_finished(job_state_from_name(s.at("state").get<std::string>()))) return s;
    } catch (const BrokerUnreachable& e) {
      const auto now = Clock::now();
      const auto waited = std::chrono::duration_cast<std::chrono::milliseconds>(now - unreachable_since);
      if (unreachable_since == Clock::time_point{}) {
        unreachable_since = now;
        reminders.emplace(patience);
        tell(std::string(e.what()) + "; waiting up to " + std::to_string(patience.count()) + " s for it");
      } else if (reminders->next() && waited >= *reminders->next()) {
        // One notice for the marks one poll passed: a stopped broker's poll
        // takes its whole --timeout.
        while (reminders->next() && waited >= *reminders->next()) reminders->advance();
        tell("still waiting for the broker at " + url + " (" +
             std::to_string(std::chrono::duration_cast<std::chrono::seconds>(waited).count()) +
             " s so far; giving up after " + std::to_string(patience.count()) + " s)");
      }
      if (now - unreachable_since > patience) throw;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
  }
}

}  // namespace rayfarm
