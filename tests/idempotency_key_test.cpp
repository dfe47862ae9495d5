// The Idempotency-Key of POST /api/jobs over a real socket (127.0.0.1, port 0
// read back): a submission sent again answers its first job, a key kept across
// a restart, refused when malformed or reused for another body, and the
// client's retries of a submission whose answer was lost.
#include <doctest/doctest.h>

#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <string>
#include <thread>
#include <vector>

#include <httplib.h>

#include "service/api_client.h"
#include "service/http_api.h"
#include "tests/http_peers.h"
#include "tests/service_scenes.h"
#include "tests/test_paths.h"
#include "tracer/text_file.h"

using namespace rayfarm;
using namespace rayfarm::http_test;

namespace {

// A POST of the tiny job with `key` as its Idempotency-Key ("" for none).
httplib::Result post_job(httplib::Client& raw, const std::string& key, int frames = 1) {
  httplib::Headers headers;
  if (!key.empty()) headers.emplace("Idempotency-Key", key);
  return raw.Post("/api/jobs", headers, submission_json(tiny_submission(frames)).dump(), "application/json");
}

// One HTTP request read whole from `fd` (head, and a body by its Content-Length).
std::string read_request(int fd) {
  std::string request;
  char buf[4096];
  size_t end = std::string::npos, length = 0;
  while (end == std::string::npos || request.size() < end + 4 + length) {
    const ssize_t n = ::recv(fd, buf, sizeof buf, 0);
    if (n <= 0) break;
    request.append(buf, static_cast<size_t>(n));
    if (end != std::string::npos || (end = request.find("\r\n\r\n")) == std::string::npos) continue;
    const size_t at = request.find("Content-Length: ");
    if (at != std::string::npos && at < end) length = std::stoul(request.substr(at + 16));
  }
  return request;
}

// The value of header `name` in a raw request, "" if it has none.
std::string header_of(const std::string& request, const std::string& name) {
  const size_t at = request.find("\r\n" + name + ": ");
  if (at == std::string::npos) return "";
  const size_t from = at + name.size() + 4;
  return request.substr(from, request.find("\r\n", from) - from);
}

}  // namespace

TEST_CASE("http api: a submission sent again with its Idempotency-Key answers the first job, not a second") {
  JobService jobs(fresh_dir("idempotent"));
  HttpApi api(jobs, any_port());
  httplib::Client raw(api.address());
  const auto first = post_job(raw, "nightly-42");
  REQUIRE(first);
  CHECK(first->status == 201);
  const auto again = post_job(raw, "nightly-42");
  REQUIRE(again);
  CHECK(again->status == 201);  // the first answer again, as it would have come
  const auto a = nlohmann::json::parse(first->body), b = nlohmann::json::parse(again->body);
  CHECK(b["id"] == a["id"]);
  CHECK(!a.contains("earlier_submission"));
  CHECK(b["earlier_submission"] == true);
  CHECK(b["scenes"] == a["scenes"]);
  CHECK(ApiClient(api.address()).list().size() == 1);
  // Another key, or none, is another job.
  const auto other = post_job(raw, "nightly-43");
  REQUIRE(other);
  CHECK(nlohmann::json::parse(other->body)["id"] != a["id"]);
  const auto none = post_job(raw, "");
  REQUIRE(none);
  CHECK(!nlohmann::json::parse(none->body).contains("earlier_submission"));
  CHECK(ApiClient(api.address()).list().size() == 3);
}

TEST_CASE("http api: an Idempotency-Key sent again with another body is refused 422 naming the key and its job") {
  JobService jobs(fresh_dir("idempotent-other-body"));
  HttpApi api(jobs, any_port());
  httplib::Client raw(api.address());
  const auto first = post_job(raw, "k1", 1);
  REQUIRE(first);
  const auto id = nlohmann::json::parse(first->body)["id"].get<uint64_t>();
  const auto other = post_job(raw, "k1", 2);
  REQUIRE(other);
  CHECK(other->status == 422);
  CHECK(nlohmann::json::parse(other->body)["error"] ==
        "Idempotency-Key 'k1': already used by job " + std::to_string(id) +
            " for another request body; a key names one submission (send a new key for a new job)");
  CHECK(ApiClient(api.address()).list().size() == 1);
  // A body refused for itself holds no key: sent right, it is the job.
  httplib::Headers headers{{"Idempotency-Key", "k2"}};
  const auto bad = raw.Post("/api/jobs", headers, R"({"scenes": []})", "application/json");
  REQUIRE(bad);
  CHECK(bad->status == 400);
  const auto good = post_job(raw, "k2");
  REQUIRE(good);
  CHECK(good->status == 201);
  CHECK(!nlohmann::json::parse(good->body).contains("earlier_submission"));
}

TEST_CASE("http api: an Idempotency-Key is kept with its job across a restart of the service") {
  const std::string dir = fresh_dir("idempotent-restart");
  uint64_t id = 0;
  {
    JobService jobs(dir);
    HttpApi api(jobs, any_port());
    httplib::Client raw(api.address());
    const auto first = post_job(raw, "across-restart");
    REQUIRE(first);
    id = nlohmann::json::parse(first->body)["id"].get<uint64_t>();
    CHECK(ApiClient(api.address()).cancel(id)["state"] == "cancelled");  // a finished job keeps it too
  }
  // Not in the status the API answers: the key is the state folder's.
  const auto stored = read_json_file(dir + "/jobs/" + std::to_string(id) + "/status.json");
  CHECK(stored["idempotency_key"] == "across-restart");
  JobService jobs(dir);
  HttpApi api(jobs, any_port());
  httplib::Client raw(api.address());
  const auto again = post_job(raw, "across-restart");
  REQUIRE(again);
  CHECK(again->status == 201);
  const auto s = nlohmann::json::parse(again->body);
  CHECK(s["id"] == id);
  CHECK(s["earlier_submission"] == true);
  CHECK(s["state"] == "cancelled");
  CHECK(!s.contains("idempotency_key"));
  const auto other = post_job(raw, "across-restart", 2);
  REQUIRE(other);
  CHECK(other->status == 422);
  CHECK(ApiClient(api.address()).list().size() == 1);
}

TEST_CASE("http api: an Idempotency-Key empty, too long, not printable ASCII or given twice is refused 400 naming it") {
  JobService jobs(fresh_dir("idempotent-bad-key"));
  HttpApi api(jobs, any_port());
  const int port = port_of(api);
  const std::string body = submission_json(tiny_submission(1)).dump();
  const auto post = [&](const std::string& headers) {
    return raw_exchange(port,
                        "POST /api/jobs HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\n" + headers +
                            "Content-Length: " + std::to_string(body.size()) + "\r\n\r\n" + body,
                        3000);
  };
  const std::string expected = "Idempotency-Key: expected 1 to 255 printable ASCII characters, found ";
  const std::pair<std::string, std::string> cases[] = {
      {"Idempotency-Key: \r\n", expected + "none"},
      {"Idempotency-Key: " + std::string(256, 'k') + "\r\n", expected + "256"},
      {"Idempotency-Key: ab\x01" "c\r\n", expected + "byte 0x01 at character 3"},
      {"Idempotency-Key: sc\xc3\xa8ne\r\n", expected + "byte 0xc3 at character 3"},
      {"Idempotency-Key: a\r\nIdempotency-Key: a\r\n", "Idempotency-Key: given 2 times, expected once"}};
  for (const auto& [headers, reason] : cases) {
    CAPTURE(headers);
    const std::string answer = post(headers);
    CHECK(answer.rfind("HTTP/1.1 400", 0) == 0);
    CHECK(answer.find("\"error\": \"" + reason + "\"") != std::string::npos);
  }
  CHECK(post("Idempotency-Key: " + std::string(255, 'k') + "\r\n").rfind("HTTP/1.1 201", 0) == 0);
  CHECK(post("Idempotency-Key: a key, with spaces ~!\r\n").rfind("HTTP/1.1 201", 0) == 0);
  CHECK(ApiClient(api.address()).list().size() == 2);
  CHECK(idempotency_key_fault("rayfarm-0123") == "");
}

TEST_CASE("http api: two submissions with one Idempotency-Key at once make one job") {
  JobService jobs(fresh_dir("idempotent-at-once"));
  const nlohmann::json body = submission_json(tiny_submission(40));
  const SubmissionKey key{"at-once", "0123456789abcdef"};
  std::vector<Submitted> made(4);
  std::vector<std::thread> threads;
  for (Submitted& m : made) threads.emplace_back([&] { m = jobs.submit(body, key); });
  for (std::thread& t : threads) t.join();
  CHECK(jobs.list().size() == 1);
  int first = 0;
  for (const Submitted& m : made) {
    CHECK(m.id == made[0].id);
    first += !m.earlier;
  }
  CHECK(first == 1);
}

TEST_CASE("http api: a submission whose answer is lost is sent again with the same key, and makes one job" *
          doctest::timeout(60)) {
  JobService jobs(fresh_dir("idempotent-retry"));
  HttpApi api(jobs, any_port());
  const int service = port_of(api);
  // Between client and service: the first request reaches the service, its
  // answer is dropped with the connection; the second's is passed on.
  std::string url;
  const int fd = silent_listener(url);
  std::vector<std::string> requests;
  std::thread proxy([&] {
    for (int i = 0; i < 2; ++i) {
      const int c = ::accept(fd, nullptr, nullptr);
      if (c < 0) return;
      requests.push_back(read_request(c));
      const std::string answer = raw_exchange(service, requests.back(), 5000);
      if (i == 1) ::send(c, answer.data(), answer.size(), MSG_NOSIGNAL);
      ::close(c);
    }
  });
  std::vector<std::string> notices;
  SubmitRetry retry;
  retry.key = random_idempotency_key();
  retry.backoff = std::chrono::milliseconds(10);
  retry.notice = [&](const std::string& text) { notices.push_back(text); };
  const uint64_t id = ApiClient(url).submit(tiny_submission(1), retry);
  proxy.join();
  ::close(fd);
  REQUIRE(requests.size() == 2);
  CHECK(header_of(requests[0], "Idempotency-Key") == retry.key);
  CHECK(header_of(requests[1], "Idempotency-Key") == retry.key);
  CHECK(retry.key.size() == 40);
  CHECK(jobs.list().size() == 1);
  CHECK(jobs.list()[0]["id"] == id);
  REQUIRE(notices.size() == 2);
  CHECK(notices[0] == "the broker at " + url + " closed the connection before answering (did it stop or restart?); "
                      "the submit may have taken effect: see rayfarm status; sending it again in 0.01 s with the "
                      "same Idempotency-Key, which makes no second job (attempt 2 of 4)");
  CHECK(notices[1] == "the broker already held this submission (Idempotency-Key " + retry.key + "): job " +
                          std::to_string(id) + ", not a second one");
}

TEST_CASE("http api: a submission answered 400 or 503 is not sent again, a lost one at most the attempts given" *
          doctest::timeout(60)) {
  httplib::Server other;
  std::atomic<int> posts{0};
  std::atomic<int> status{400};
  other.Post("/api/jobs", [&](const httplib::Request&, httplib::Response& res) {
    posts += 1;
    res.status = status;
    res.set_content(R"({"error": "no"})", "application/json");
  });
  const int port = other.bind_to_any_port("127.0.0.1");
  REQUIRE(port > 0);
  std::thread serving([&other] { other.listen_after_bind(); });
  std::string url = "http://127.0.0.1:" + std::to_string(port);
  SubmitRetry retry;
  retry.key = "k";
  retry.backoff = std::chrono::milliseconds(1);
  CHECK_THROWS_WITH_AS(ApiClient(url).submit(tiny_submission(1), retry), "submit: no", ApiError);
  CHECK(posts == 1);
  status = 503;
  CHECK_THROWS_AS(ApiClient(url).submit(tiny_submission(1), retry), BrokerUnreachable);
  CHECK(posts == 2);
  other.stop();
  serving.join();

  // A listener that reads each request and closes unanswered: 3 attempts, then the key to go on with.
  const int fd = silent_listener(url);
  std::thread dying([fd] {
    for (int i = 0; i < 3; ++i) {
      const int c = ::accept(fd, nullptr, nullptr);
      if (c < 0) return;
      read_answer(c, 300);
    }
  });
  retry.attempts = 3;
  CHECK_THROWS_WITH_AS(ApiClient(url).submit(tiny_submission(1), retry),
                       doctest::Contains("(sent 3 times; to try again without a second job: --idempotency-key k)"),
                       AnswerLost);
  dying.join();
  ::close(fd);
}
