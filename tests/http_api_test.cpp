// HttpApi + ApiClient over a real socket (127.0.0.1, port 0 read back): submit,
// status, cancel, fetch, errors as JSON reasons with their status codes, the
// bearer token, and the refusal to serve beyond loopback without one.
#include <doctest/doctest.h>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <mutex>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>
#include <thread>

#include <httplib.h>

#include "service/api_client.h"
#include "service/http_api.h"
#include "service/http_connection.h"
#include "tests/http_peers.h"
#include "tests/run_command.h"
#include "tests/service_scenes.h"
#include "tests/test_files.h"
#include "tests/test_paths.h"
#include "tracer/error.h"
#include "tracer/text_file.h"

using namespace rayfarm;
using namespace rayfarm::http_test;
namespace fs = std::filesystem;

TEST_CASE("http api: submit, status, list, cancel, errors carry a reason") {
  JobService jobs(fresh_dir("basic"));
  HttpApi api(jobs, any_port());
  CHECK(api.address().rfind("http://127.0.0.1:", 0) == 0);
  ApiClient client(api.address());
  const uint64_t id = client.submit(tiny_submission(3));
  const auto s = client.status(id);
  CHECK(s["state"] == "queued");
  CHECK(s["frames"] == 3);
  CHECK(s["rows_total"] == 72);
  CHECK(s["scenes"][2] == "f2.nff");
  CHECK(client.list().size() == 1);

  Submission bad = tiny_submission(1);
  bad.scenes[0].text = "s 0 0 0 1\n";  // no view
  try {
    client.submit(bad);
    FAIL("a scene without a view was accepted");
  } catch (const ApiError& e) {
    CHECK(e.status == 400);
    CHECK(std::string(e.what()).find("scenes[0] (f0.nff)") != std::string::npos);
  }
  CHECK_THROWS_WITH_AS(client.status(77), doctest::Contains("no job 77"), ApiError);
  CHECK_THROWS_WITH_AS(client.frame(id, 1), doctest::Contains("not rendered yet"), ApiError);
  CHECK(client.cancel(id)["state"] == "cancelled");
  CHECK_THROWS_WITH_AS(client.cancel(id), doctest::Contains("already cancelled"), ApiError);
  CHECK(client.list().size() == 1);
}

TEST_CASE("http api: a record of a frame the job does not have is 404, as its image, not 409 not yet") {
  // It was 409 "no record for frame 5 yet": a client waiting for it waited forever.
  JobService jobs(fresh_dir("record-range"));
  HttpApi api(jobs, any_port());
  ApiClient client(api.address());
  const uint64_t id = client.submit(tiny_submission(3));
  httplib::Client raw(api.address());
  const std::string job = "/api/jobs/" + std::to_string(id);
  for (const char* kind : {"/records/", "/frames/"}) {
    CAPTURE(kind);
    const auto past = raw.Get(job + kind + "4");
    REQUIRE(past);
    CHECK(past->status == 404);
    CHECK(nlohmann::json::parse(past->body)["error"] == "job " + std::to_string(id) + " has 3 frame(s)");
    const auto queued = raw.Get(job + kind + "3");
    REQUIRE(queued);
    CHECK(queued->status == 409);  // the last frame: not yet
  }
}

TEST_CASE("http api: a frame of a cancelled job is said never to come, not to be rendered yet") {
  // It was 409 "job 1 frame 1 is not rendered yet (cancelled)".
  JobService jobs(fresh_dir("cancelled-frame"));
  HttpApi api(jobs, any_port());
  ApiClient client(api.address());
  const uint64_t id = client.submit(tiny_submission(2));
  const std::string job = "job " + std::to_string(id);
  CHECK_THROWS_WITH_AS(client.frame(id, 1), ("fetch: " + job + " frame 1 is not rendered yet (queued)").c_str(), ApiError);
  client.cancel(id);
  CHECK_THROWS_WITH_AS(client.frame(id, 1),
                       ("fetch: " + job + " frame 1 is not rendered: the job is cancelled and will not render it").c_str(),
                       ApiError);
  httplib::Client raw(api.address());
  const auto record = raw.Get("/api/jobs/" + std::to_string(id) + "/records/2");
  REQUIRE(record);
  CHECK(record->status == 409);  // no longer
  CHECK(nlohmann::json::parse(record->body)["error"] ==
        job + " has no record for frame 2: the job is cancelled and will not render it");
}

TEST_CASE("http api: a scene named or commented in Latin-1, not UTF-8, is submitted as rayfarm render reads it") {
  JobService jobs(fresh_dir("latin1"));
  HttpApi api(jobs, any_port());
  Submission s = tiny_submission(1);
  s.scenes[0].name = "sc\xe8ne.nff";
  s.scenes[0].text = "# sc\xe8ne de test\n" + s.scenes[0].text;
  const uint64_t id = ApiClient(api.address()).submit(s);
  const auto status = jobs.status(id);
  CHECK(status["scenes"][0] == "sc\xef\xbf\xbdne.nff");
  CHECK(status["rows_total"] == 24);
}

TEST_CASE("http api: a cut request body is refused with a short reason, not its scene quoted whole") {
  JobService jobs(fresh_dir("cut-body"));
  HttpApi api(jobs, any_port());
  httplib::Client raw(api.address());
  const std::string scene(100000, 'v');
  for (const std::string& body : {R"({"scenes": [{"name": "a.nff", "nff": ")" + scene,
                                   "[1" + std::string(100000, '0') + "]",
                                   "{\"" + scene + "\": 1, \"" + scene + "\": 2}"}) {
    const auto r = raw.Post("/api/jobs", body, "application/json");
    REQUIRE(r);
    CHECK(r->status == 400);
    const std::string reason = nlohmann::json::parse(r->body)["error"].get<std::string>();
    CAPTURE(reason.substr(0, 200));
    CHECK(reason.rfind("request body: invalid JSON: ", 0) == 0);
    CHECK(reason.size() < 300);
  }
}

TEST_CASE("http api: malformed bodies are answered as JSON, the service keeps serving") {
  JobService jobs(fresh_dir("malformed"));
  HttpApi api(jobs, any_port());
  ApiClient client(api.address());
  const uint64_t id = client.submit(tiny_submission(1));
  httplib::Client raw(api.address());
  for (const auto& [body, reason] : std::vector<std::pair<std::string, std::string>>{
           {"{not json", "invalid JSON"},
           {R"({"scenes": [{"name": "a.nff", "nff": "s 0 0 0 1\n", "name": "b.nff"}]})", "duplicate key \"name\""},
           {"[1, 2]", "expected a JSON object"},
           {R"({"scenes": [{"name": "x.nff"}]})", "scenes[0].nff: missing"},
           {R"({"scenes": [{"name": "x.nff", "nff": 5}]})", "scenes[0].nff: expected a string"},
           {R"({"scenes": [], "priority": 1})", "scenes: expected an array of 1.."}}) {
    CAPTURE(body);
    const auto r = raw.Post("/api/jobs", body, "application/json");
    REQUIRE(r);
    CHECK(r->status == 400);
    CHECK(nlohmann::json::parse(r->body)["error"].get<std::string>().find(reason) != std::string::npos);
  }
  const auto missing = raw.Get("/nothing/here");
  REQUIRE(missing);
  CHECK(missing->status == 404);
  CHECK(nlohmann::json::parse(missing->body).contains("error"));
  // Announced, never sent: the service drains what comes until its 5 s read timeout, then answers.
  const std::string too_big = raw_exchange(
      port_of(api), "POST /api/jobs HTTP/1.1\r\nHost: x\r\nContent-Length: 600000000\r\n\r\n", 10000);
  CHECK(too_big.rfind("HTTP/1.1 413", 0) == 0);
  CHECK(too_big.find(R"("error": "request body larger than 512 MiB")") != std::string::npos);
  const auto huge_id = raw.Get("/api/jobs/99999999999999999999999");
  REQUIRE(huge_id);
  CHECK(huge_id->status == 404);
  CHECK(client.status(id)["state"] == "queued");
  CHECK(client.list().size() == 1);
}

TEST_CASE("http api: a reason quoting bytes that are not UTF-8 is answered 400 with it, not 500 without one") {
  JobService jobs(fresh_dir("not-utf8"));
  HttpApi api(jobs, any_port());
  httplib::Client raw(api.address());
  const auto r = raw.Post("/api/jobs", "{\"scenes\": \"\xff\"}", "application/json");
  REQUIRE(r);
  CHECK(r->status == 400);
  CHECK(nlohmann::json::parse(r->body)["error"].get<std::string>().find("request body: invalid JSON") == 0);
  // The header's value is quoted in the reason as sent.
  const std::string answer = raw_exchange(
      port_of(api), "GET /api/jobs HTTP/1.1\r\nHost: x\r\nContent-Length: 1\xff\r\nConnection: close\r\n\r\n", 5000);
  CHECK(answer.rfind("HTTP/1.1 400", 0) == 0);
  CHECK(answer.find("Content-Length: expected a number of bytes, found '1\xef\xbf\xbd'") != std::string::npos);
  CHECK(raw.Get("/api/jobs")->status == 200);
}

TEST_CASE("http api: a job sent as a form (curl -d's default) over httplib's limit is told so, not 'over 512 MiB'") {
  JobService jobs(fresh_dir("form-body"));
  HttpApi api(jobs, any_port());
  Submission s = tiny_submission(1);
  s.scenes[0].text = "# " + std::string(20000, 'x') + "\n" + s.scenes[0].text;
  const std::string body = submission_json(s).dump();
  httplib::Client raw(api.address());
  const auto form = raw.Post("/api/jobs", body, "application/x-www-form-urlencoded");
  REQUIRE(form);
  CHECK(form->status == 413);
  const std::string reason = nlohmann::json::parse(form->body)["error"];
  CHECK(reason.find("sent as a form") != std::string::npos);
  CHECK(reason.find("Content-Type: application/json") != std::string::npos);
  CHECK(jobs.list().empty());
  const auto as_json = raw.Post("/api/jobs", body, "application/json");
  REQUIRE(as_json);
  CHECK(as_json->status == 201);
}

TEST_CASE("http api: a request path over httplib's limit is refused 414 with a reason, not 'HTTP 414'") {
  JobService jobs(fresh_dir("long-path"));
  HttpApi api(jobs, any_port());
  httplib::Client raw(api.address());
  const auto long_path = raw.Get("/api/jobs/" + std::string(10000, '7'));
  REQUIRE(long_path);
  CHECK(long_path->status == 414);
  CHECK(nlohmann::json::parse(long_path->body)["error"] == "request path (with its query) longer than 8192 bytes");
}

TEST_CASE("http api: a bearer token is required when set, and beyond loopback") {
  JobService jobs(fresh_dir("token"));
  HttpApi api(jobs, any_port("s3cret-token"));
  CHECK_THROWS_WITH_AS(ApiClient(api.address()).list(), doctest::Contains("bearer token"), ApiError);
  CHECK_THROWS_AS(ApiClient(api.address(), "wrong").list(), ApiError);
  CHECK(ApiClient(api.address(), "s3cret-token").list().empty());

  HttpOptions open = any_port();
  open.host = "0.0.0.0";
  CHECK_THROWS_WITH_AS(HttpApi(jobs, open), doctest::Contains("needs a bearer token"), InputError);
  CHECK(is_loopback("127.0.0.1"));
  CHECK(is_loopback("::1"));
  CHECK(!is_loopback("10.0.0.5"));
  CHECK(parse_http_address("0.0.0.0:9000").port == 9000);
  CHECK_THROWS_AS(parse_http_address("localhost"), InputError);
  CHECK_THROWS_AS(parse_http_address("localhost:99999"), InputError);
  const std::string token_file = fresh_dir("token-file");
  write_text_file(token_file, "  \n");
  CHECK_THROWS_WITH_AS(read_token_file(token_file), doctest::Contains("empty"), InputError);
  write_text_file(token_file, "abc123\n");
  CHECK(read_token_file(token_file) == "abc123");
}

TEST_CASE("http api: a token file of two lines or with a control character is refused, not a token no client can send") {
  // The broker started with it and answered 401 to every client given the same file.
  const std::string token_file = fresh_dir("token-lines");
  write_text_file(token_file, "abc123\n# made 2026-12-07\n");
  CHECK_THROWS_WITH_AS(read_token_file(token_file),
                       (token_file + ": expected the token on one line of printable characters, found a line break "
                                     "after 6 characters (no HTTP header can carry it)")
                           .c_str(),
                       InputError);
  write_text_file(token_file, "abc\x01" "123\n");
  CHECK_THROWS_WITH_AS(read_token_file(token_file), doctest::Contains("found control character 0x01 after 3 characters"),
                       InputError);
  write_text_file(token_file, "\r\n  s3cret token\t\r\n");  // white space around it, a space within: as before
  CHECK(read_token_file(token_file) == "s3cret token");
  // The broker refuses it at start, naming the option and the file.
  write_text_file(token_file, "abc123\nxyz\n");
  const auto r = test::run_command("timeout 10 " + test::rayfarm_exe() + " broker --serve --state " + token_file +
                                   ".state --http 127.0.0.1:0 --bind 'tcp://127.0.0.1:*' --announce "
                                   "'tcp://127.0.0.1:*' --token-file " + token_file);
  CHECK(r.exit_code == 1);
  CHECK(r.output.find("--token-file " + token_file + ": expected the token on one line") != std::string::npos);
  CHECK(r.output.find("xyz") == std::string::npos);  // never the secret
}

TEST_CASE("http api: the auth scheme is case-insensitive (bearer, BEARER), the token is not") {
  JobService jobs(fresh_dir("token-scheme"));
  HttpApi api(jobs, any_port("s3cret-token"));
  httplib::Client raw(api.address());
  const auto status_with = [&raw](const std::string& authorization) {
    return raw.Get("/api/jobs", {{"Authorization", authorization}})->status;
  };
  for (const char* accepted :
       {"Bearer s3cret-token", "bearer s3cret-token", "BEARER s3cret-token", "bEaReR  s3cret-token"}) {
    CAPTURE(accepted);
    CHECK(status_with(accepted) == 200);
  }
  for (const char* refused : {"Bearer S3CRET-TOKEN", "Bearers3cret-token", "Basic s3cret-token", "bearer",
                              "s3cret-token", "Bearer s3cret-token2"}) {
    CAPTURE(refused);
    CHECK(status_with(refused) == 401);
  }
}

TEST_CASE("http api: with a token, the status page's files answer HEAD as they answer GET, without one") {
  JobService jobs(fresh_dir("token-head"));
  StatusBoard board;
  HttpApi api(jobs, any_port("s3cret-token"), &board);
  httplib::Client raw(api.address());
  for (const char* path : {"/", "/status.js"}) {
    CAPTURE(path);
    CHECK(raw.Get(path)->status == 200);
    CHECK(raw.Head(path)->status == 200);
  }
  CHECK(raw.Head("/api/jobs")->status == 401);
}

namespace {

// A service with a status board behind a token, and GET /api/service on it.
struct ServiceRoute {
  JobService jobs;
  StatusBoard board;
  HttpApi api;
  httplib::Client raw;
  const httplib::Headers auth{{"Authorization", "Bearer s3cret-token"}};
  explicit ServiceRoute(const char* dir)
      : jobs(fresh_dir(dir)), api(jobs, any_port("s3cret-token"), &board), raw(api.address()) {}
  nlohmann::json get() {
    const auto r = raw.Get("/api/service", auth);
    REQUIRE(r);
    REQUIRE(r->status == 200);
    CHECK(r->get_header_value("Cache-Control") == "no-store");
    return nlohmann::json::parse(r->body);
  }
};

}  // namespace

TEST_CASE("http api: on a keyed farm /api/service gives the whole worker command, the broker's public key and"
          " the allow folder, never its secret key") {
  CHECK(broker_public_key_beside("/etc/rayfarm/broker.key") == "/etc/rayfarm/broker.pub");
  CHECK(broker_public_key_beside("keys/head.key") == "keys/head.pub");
  CHECK(broker_public_key_beside("/etc/rayfarm/broker.secret") == "BROKER.pub");  // no guess at another name
  CHECK(broker_public_key_beside(".key") == "BROKER.pub");
  ServiceRoute service("service-keys");
  service.board.set_worker_endpoint("tcp://0.0.0.0:5555");
  service.board.set_worker_keys(broker_public_key_beside("/etc/rayfarm/broker.key"), "/etc/rayfarm/allow");
  const nlohmann::json answer = service.get();
  CHECK(answer ==
        nlohmann::json{{"workers", "tcp://0.0.0.0:5555"},
                       {"worker_connect", "tcp://HEAD:5555"},
                       {"worker_command",
                        "rayfarm worker --connect tcp://HEAD:5555 --key WORKER.key --broker-key /etc/rayfarm/broker.pub"},
                       {"allow", "/etc/rayfarm/allow"}});
  CHECK(answer.dump().find("broker.key") == std::string::npos);
  // A path a shell would split is quoted, a quote in it too.
  service.board.set_worker_keys("/srv/my keys/it's.pub", "/srv/my keys/allow");
  CHECK(service.get()["worker_command"] ==
        "rayfarm worker --connect tcp://HEAD:5555 --key WORKER.key --broker-key '/srv/my keys/it'\\''s.pub'");
}

TEST_CASE("http api: /api/service of a keyed farm whose folders are not UTF-8 answers them escaped as \\xNN, not 500") {
  // A folder named in Latin-1 ("cl\xe9s"): dump() threw on its byte, and every
  // poll of the page was answered 500; then U+FFFD stood for it, naming no file.
  ServiceRoute service("service-latin1");
  service.board.set_worker_endpoint("tcp://0.0.0.0:5555");
  const std::string latin1 = "/srv/cl\xe9s";
  service.board.set_worker_keys(latin1 + "/broker.pub", latin1 + "/allow");
  const nlohmann::json answer = service.get();
  CHECK(answer == nlohmann::json{{"workers", "tcp://0.0.0.0:5555"},
                                 {"worker_connect", "tcp://HEAD:5555"},
                                 {"worker_command", "rayfarm worker --connect tcp://HEAD:5555 --key WORKER.key "
                                                    "--broker-key $'/srv/cl\\xe9s/broker.pub'"},
                                 {"allow", "/srv/cl\\xe9s/allow"}});
  // Pasted into bash, the command names the very file; a quote and an ESC too.
  service.board.set_worker_keys(latin1 + "/it's\x1b.pub", latin1 + "/allow");
  const std::string command = service.get()["worker_command"];
  CHECK(command.find("--broker-key $'/srv/cl\\xe9s/it\\'s\\x1b.pub'") != std::string::npos);
  const std::filesystem::path dir = test::scratch_dir("service-latin1-paste");
  const std::string script =
      test::write_file(dir / "paste.sh", "rayfarm() { printf '%s\\n' \"$@\"; }\n" + command + "\n");
  const test::CommandResult pasted = test::run_command("bash " + script);
  CHECK(pasted.exit_code == 0);
  CHECK(pasted.output.find("--broker-key\n" + latin1 + "/it's\x1b.pub\n") != std::string::npos);
  std::filesystem::remove_all(dir);
}

TEST_CASE("http api: /api/service names the worker socket as bound and as a worker connects to it, token and all") {
  ServiceRoute service("service-endpoint");
  CHECK(service.get() == nlohmann::json{{"workers", nullptr},
                                        {"worker_connect", nullptr},
                                        {"worker_command", nullptr},
                                        {"allow", nullptr}});  // not bound yet
  // Bound to every interface, no worker can connect to that address: the
  // head node's name is the operator's to put in, the port is the broker's.
  service.board.set_worker_endpoint("tcp://0.0.0.0:47123");
  CHECK(service.get() == nlohmann::json{{"workers", "tcp://0.0.0.0:47123"},
                                        {"worker_connect", "tcp://HEAD:47123"},
                                        {"worker_command", "rayfarm worker --connect tcp://HEAD:47123"},
                                        {"allow", nullptr}});
  service.board.set_worker_endpoint("tcp://[::]:6000");
  CHECK(service.get()["worker_connect"] == "tcp://HEAD:6000");
  service.board.set_worker_endpoint("tcp://10.1.2.3:6000");
  CHECK(service.get()["worker_connect"] == "tcp://10.1.2.3:6000");
  // The API's rules, as for every resource: the token, the methods, no other path.
  CHECK(service.raw.Get("/api/service")->status == 401);
  const auto posted = service.raw.Post("/api/service", service.auth, "", "text/plain");
  REQUIRE(posted);
  CHECK(posted->status == 405);
  CHECK(posted->get_header_value("Allow") == "GET, HEAD, OPTIONS");
  CHECK(service.raw.Get("/api/service/1", service.auth)->status == 404);
  CHECK(service.raw.Get("/api/services", service.auth)->status == 404);
}

TEST_CASE("http api: a second broker cannot bind a port in use (it would take half the requests)") {
  JobService first_jobs(fresh_dir("port-first"));
  HttpApi first(first_jobs, any_port());
  JobService second_jobs(fresh_dir("port-second"));
  HttpOptions same = any_port();
  same.port = port_of(first);
  CHECK_THROWS_WITH_AS(HttpApi(second_jobs, same), doctest::Contains("cannot bind"), InputError);
  first_jobs.submit(submission_json(tiny_submission(1)));
  CHECK(ApiClient(first.address()).list().size() == 1);
}

TEST_CASE("http api: a POST without a length (curl -X POST URL) is answered 411 at once, not after the read timeout") {
  JobService jobs(fresh_dir("no-length"));
  HttpApi api(jobs, any_port());
  const uint64_t id = jobs.submit(submission_json(tiny_submission(1)));
  const std::string answer = raw_exchange(
      port_of(api), "POST /api/jobs/" + std::to_string(id) + "/cancel HTTP/1.1\r\nHost: x\r\n\r\n", 2000);
  CHECK(answer.rfind("HTTP/1.1 411", 0) == 0);
  CHECK(answer.find("needs a Content-Length header") != std::string::npos);
  CHECK(jobs.status(id)["state"] == "queued");
  const std::string empty_body = raw_exchange(
      port_of(api), "POST /api/jobs/" + std::to_string(id) + "/cancel HTTP/1.1\r\nHost: x\r\nContent-Length: 0\r\n\r\n",
      2000);
  CHECK(empty_body.rfind("HTTP/1.1 200", 0) == 0);
  CHECK(jobs.status(id)["state"] == "cancelled");
}

TEST_CASE("http api: a known path asked with another method is answered 405 with its methods, OPTIONS 204") {
  JobService jobs(fresh_dir("methods"));
  StatusBoard board;
  HttpApi api(jobs, any_port(), &board);
  const uint64_t id = jobs.submit(submission_json(tiny_submission(1)));
  const std::string job = "/api/jobs/" + std::to_string(id);
  httplib::Client raw(api.address());
  const auto refused = [](const httplib::Result& r, const std::string& allow) {
    REQUIRE(r);
    CHECK(r->status == 405);
    CHECK(r->get_header_value("Allow") == allow);
    CHECK(nlohmann::json::parse(r->body)["error"].get<std::string>().find("method not allowed") != std::string::npos);
  };
  refused(raw.Put("/api/jobs", "{}", "application/json"), "GET, HEAD, POST, OPTIONS");
  refused(raw.Delete(job), "GET, HEAD, OPTIONS");
  refused(raw.Get(job + "/cancel"), "POST, OPTIONS");
  refused(raw.Post(job + "/frames/1", "", "text/plain"), "GET, HEAD, OPTIONS");
  refused(raw.Patch("/api/workers", "{}", "application/json"), "GET, HEAD, OPTIONS");
  refused(raw.Post("/metrics", "", "text/plain"), "GET, HEAD, OPTIONS");
  refused(raw.Delete("/"), "GET, HEAD, OPTIONS");
  const auto options = raw.Options(job + "/records/1");
  REQUIRE(options);
  CHECK(options->status == 204);
  CHECK(options->get_header_value("Allow") == "GET, HEAD, OPTIONS");
  CHECK(raw.Head(job)->status == 200);
  CHECK(raw.Delete("/api/nothing")->status == 404);
  // Told before any body is read: a PUT without a length is answered at once, not after the read timeout.
  CHECK(raw_exchange(port_of(api), "PUT " + job + " HTTP/1.1\r\nHost: x\r\n\r\n", 2000).rfind("HTTP/1.1 405", 0) == 0);
  const std::string trace = raw_exchange(port_of(api), "TRACE " + job + " HTTP/1.1\r\nHost: x\r\n\r\n", 2000);
  CHECK(trace.rfind("HTTP/1.1 405", 0) == 0);
  CHECK(jobs.status(id)["state"] == "queued");
}

TEST_CASE("http api: a job id or frame number has one spelling, /api/jobs/01 is no path") {
  JobService jobs(fresh_dir("spelling"));
  StatusBoard board;
  HttpApi api(jobs, any_port(), &board);
  const uint64_t id = jobs.submit(submission_json(tiny_submission(1)));
  REQUIRE(id == 1);
  httplib::Client raw(api.address());
  CHECK(raw.Get("/api/jobs/1")->status == 200);
  for (const char* path : {"/api/jobs/01", "/api/jobs/001", "/api/jobs/+1", "/api/jobs/1/frames/01",
                           "/api/jobs/01/frames/1", "/api/jobs/1/records/001", "/api/jobs/01/preview.png"}) {
    CAPTURE(path);
    const auto r = raw.Get(path);
    REQUIRE(r);
    CHECK(r->status == 404);
    CHECK(nlohmann::json::parse(r->body)["error"] == "no such resource (see docs/api.md)");
  }
  CHECK(raw.Post("/api/jobs/01/cancel", "", "text/plain")->status == 404);
  CHECK(jobs.status(id)["state"] == "queued");
}

TEST_CASE("http api: an encoded slash (%2F) in a path is no separator, 1%2Fcancel is no job id and cancels nothing") {
  JobService jobs(fresh_dir("encoded-slash"));
  StatusBoard board;
  HttpApi api(jobs, any_port(), &board);
  const uint64_t id = jobs.submit(submission_json(tiny_submission(1)));
  REQUIRE(id == 1);
  const auto answer_to = [&](const std::string& request_line, const std::string& more = "") {
    return exchange_until_closed(port_of(api), request_line + "\r\nHost: x\r\n" + more + "Connection: close\r\n\r\n",
                                 2000);
  };
  // Before: job 1 cancelled (200).
  const std::string cancel = answer_to("POST /api/jobs/1%2Fcancel HTTP/1.1", "Content-Length: 0\r\n");
  CHECK(cancel.rfind("HTTP/1.1 404", 0) == 0);
  CHECK(cancel.find("no such resource (see docs/api.md)") != std::string::npos);
  CHECK(jobs.status(id)["state"] == "queued");
  // Before: job 1's status, its frame's or record's 409, a 405 for the cancel, the preview's "no image of job 1".
  for (const std::string target :
       {"/api/jobs%2F1", "/api/jobs%2f1", "/api/jobs/1%2Fframes/1", "/api/jobs/1%2frecords%2F1", "/api/jobs/1%2Fcancel",
        "/api/jobs/1%2Fpreview.png", "%2Fapi/jobs/1", "http://x/api/jobs/1%2Fframes%2F1"}) {
    CAPTURE(target);
    const std::string answer = answer_to("GET " + target + " HTTP/1.1");
    CHECK(answer.rfind("HTTP/1.1 404", 0) == 0);
    CHECK(answer.find("no such resource (see docs/api.md)") != std::string::npos);
  }
  // Other escapes are decoded as before, and a query may hold an encoded slash.
  CHECK(answer_to("GET /api/jobs/%31 HTTP/1.1").rfind("HTTP/1.1 200", 0) == 0);
  CHECK(answer_to("GET /api/jobs/1?next=%2Fapi%2Fjobs HTTP/1.1").rfind("HTTP/1.1 200", 0) == 0);
  CHECK(jobs.status(id)["state"] == "queued");
}

TEST_CASE("http api: the clients read a job id as the API's paths do, 007 is refused naming JOB") {
  JobService jobs(fresh_dir("client-spelling"));
  HttpApi api(jobs, any_port());
  REQUIRE(jobs.submit(submission_json(tiny_submission(1))) == 1);
  httplib::Client raw(api.address());
  // `rayfarm status 007` showed job 7, though /api/jobs/007 is a 404.
  for (const std::string text : {"01", "007", "+1", "0x1", " 1", "1 ", "", "-1", "1e3", "12345678901234567890"}) {
    CAPTURE(text);
    CHECK_THROWS_WITH_AS(parse_job_id(text), doctest::Contains(("JOB: expected a job id, digits without leading "
                                                                "zeros (7, not 07), at most 19, found '" + text + "'")
                                                                   .c_str()),
                         InputError);
    if (!text.empty() && text.find(' ') == std::string::npos) CHECK(raw.Get("/api/jobs/" + text)->status == 404);
  }
  CHECK(parse_job_id("1") == 1);
  CHECK(parse_job_id("0") == 0);
  // A long id the API takes (19 digits) is no "not a number": 16 digits were refused so.
  CHECK(parse_job_id("1234567890123456") == 1234567890123456ull);
  CHECK(parse_job_id("9999999999999999999") == 9999999999999999999ull);
  CHECK(raw.Get("/api/jobs/9999999999999999999")->status == 404);
  CHECK(nlohmann::json::parse(raw.Get("/api/jobs/9999999999999999999")->body)["error"] == "no job 9999999999999999999");
  CHECK(ApiClient(api.address()).status(parse_job_id("1"))["id"] == 1);
  const std::string long_text(100, '0');
  CHECK_THROWS_WITH_AS(parse_job_id(long_text), doctest::Contains(("found '" + long_text.substr(0, 40) + "...'").c_str()),
                       InputError);
  // Cut as every quote of input is (quoted_excerpt), between characters: the
  // 40th byte here is the first of an e-acute.
  const std::string accented = std::string(39, '1') + "\xc3\xa9\xc3\xa9";
  CHECK_THROWS_WITH_AS(parse_job_id(accented), doctest::Contains(("found '" + std::string(39, '1') + "...'").c_str()),
                       InputError);
}

TEST_CASE("http api: a submit the service refuses at its connection limit mid-body says so, not killed by SIGPIPE") {
  JobService jobs(fresh_dir("refused-mid-body"));
  HttpOptions options = any_port();
  options.max_connections = 4;  // 2 from one address
  HttpApi api(jobs, options);
  const int port = port_of(api);
  const std::vector<int> held = {connect_from("127.0.0.1", port), connect_from("127.0.0.1", port)};
  // A body far larger than the sockets' buffers: the service answers 503 and
  // closes while it is still going out. Before, the client died of SIGPIPE
  // (exit 141) without a word.
  const std::string scene = fresh_dir("refused-mid-body-scene") + ".nff";
  std::string text = test::tiny_scene(0);
  for (int i = 0; i < 40000; ++i) text += "s 0 0 -10 0.125\n";
  write_text_file(scene, text);
  for (int attempt = 0; attempt < 3; ++attempt) {
    // As from a user's shell: this test process ignores SIGPIPE, and its children would inherit that.
    const test::CommandResult r = test::run_command("env --default-signal=PIPE " + test::rayfarm_exe() +
                                                    " submit --broker " + api.address() + " " + scene);
    CAPTURE(r.output);
    CHECK(r.exit_code == 1);
    const bool busy = r.output.find("is busy (HTTP 503): this address holds 2 connections") != std::string::npos;
    const bool cut = r.output.find("closed the connection while the submit was being sent (busy, or stopping?); "
                                   "nothing was taken: retry later") != std::string::npos;
    CHECK((busy || cut));
  }
  CHECK(jobs.list().empty());
  for (int fd : held) ::close(fd);
}

TEST_CASE("http api: connections left open and idle (status page tabs) do not hold back an answer") {
  JobService jobs(fresh_dir("idle"));
  HttpApi api(jobs, any_port());
  std::vector<int> idle;
  for (int i = 0; i < 40; ++i) idle.push_back(connect_to(port_of(api)));
  httplib::Client client(api.address());
  client.set_connection_timeout(3);
  client.set_read_timeout(3);  // far above an answer's time, far below the idle connections' timeouts added up
  const auto r = client.Get("/api/jobs");
  CHECK(r);
  if (r) CHECK(r->status == 200);
  for (int fd : idle) ::close(fd);
}

TEST_CASE("http api: more idle connections than server threads do not hold back an answer, and still time out" *
          doctest::timeout(60)) {
  JobService jobs(fresh_dir("many-idle"));
  HttpApi api(jobs, any_port());
  // Each idle connection held one of the 64 threads for the 2 s keep-alive:
  // with 200 open, an answer waited about 6 s (with 600, 18 s).
  std::vector<int> idle;
  for (int i = 0; i < 200; ++i) idle.push_back(connect_to(port_of(api)));
  httplib::Client client(api.address());
  client.set_connection_timeout(2);
  client.set_read_timeout(2);
  const auto started = std::chrono::steady_clock::now();
  const auto r = client.Get("/api/jobs");
  CHECK(r);
  if (r) CHECK(r->status == 200);
  CHECK(std::chrono::steady_clock::now() - started < std::chrono::seconds(1));
  // Waiting costs no thread, but the keep-alive time still ends each.
  for (int fd : idle) {
    pollfd p{fd, POLLIN, 0};
    char byte;
    CHECK(::poll(&p, 1, 5000) == 1);
    CHECK(::recv(fd, &byte, 1, 0) == 0);
    ::close(fd);
  }
}

TEST_CASE("http api: the broker URL may end in '/' (the status page's address), a path is refused, not retried") {
  JobService jobs(fresh_dir("url"));
  HttpApi api(jobs, any_port());
  CHECK(ApiClient(api.address() + "/").list().empty());
  CHECK_THROWS_WITH_AS(ApiClient(api.address() + "/api"), doctest::Contains("has a path; expected http://HOST:PORT"),
                       InputError);
}

TEST_CASE("http api: a broker URL httplib would misread (query, user, bad port, scheme) is refused, not retried") {
  JobService jobs(fresh_dir("url-form"));
  HttpApi api(jobs, any_port());
  const std::string port = std::to_string(port_of(api));
  const std::vector<std::string> misread = {
      "http://127.0.0.1:" + port + "?x", "http://127.0.0.1:" + port + "#x", "http://user@127.0.0.1:" + port,
      "http://127.0.0.1:99999",          "http://127.0.0.1:0",             "http://127.0.0.1:",
      "http://127.0.0.1:abc",            "HTTP://127.0.0.1:" + port,       "ftp://127.0.0.1:" + port,
      " http://127.0.0.1:" + port};
  for (const std::string& url : misread) {
    CAPTURE(url);
    CHECK_THROWS_WITH_AS(ApiClient{url}, doctest::Contains("is not http://HOST:PORT"), InputError);
  }
  CHECK(ApiClient("127.0.0.1:" + port).list().empty());
  CHECK(ApiClient("http://localhost:" + port).list().empty());
  CHECK_NOTHROW(ApiClient("http://[::1]:" + port));
}

TEST_CASE("http api: a reverse proxy's 502 while the broker behind it restarts is waited out, not a refusal") {
  httplib::Server proxy;
  std::atomic<int> polls{0};
  proxy.Get("/api/jobs/7", [&polls](const httplib::Request&, httplib::Response& res) {
    if (++polls <= 3) {
      res.status = 502;
      res.set_content("<html><body><h1>502 Bad Gateway</h1></body></html>\n", "text/html");
    } else {
      res.set_content(R"({"id": 7, "state": "done", "frames": 1, "frames_done": 1, "rows_done": 24, "rows_total": 24,
                          "resumed_rows": 0, "rerendered_rows": 0})",
                      "application/json");
    }
  });
  const int port = proxy.bind_to_any_port("127.0.0.1");
  REQUIRE(port > 0);
  std::thread serving([&proxy] { proxy.listen_after_bind(); });
  ApiClient client("http://127.0.0.1:" + std::to_string(port));
  CHECK_THROWS_WITH_AS(client.status(7), doctest::Contains("cannot reach the broker (HTTP 502)"), BrokerUnreachable);
  std::vector<std::string> notices;  // told once when it stops answering and once when it answers again
  CHECK(client.wait(7, std::chrono::seconds(30), [&](const std::string& n) { notices.push_back(n); })["state"] ==
        "done");
  CHECK(polls == 4);
  REQUIRE(notices.size() == 2);
  CHECK(notices[0].find("(HTTP 502); waiting up to 30 s for it") != std::string::npos);
  CHECK(notices[1].find("answers again") != std::string::npos);
  proxy.stop();
  serving.join();
}

TEST_CASE("http api: fetch --wait says a busy broker's reason escaped, as it says its errors") {
  // The reason of a 503 is the broker's text (or whatever answers on its
  // port): its ESC and BEL reached the terminal as they were.
  httplib::Server busy;
  std::atomic<int> polls{0};
  busy.Get("/api/jobs/7", [&polls](const httplib::Request&, httplib::Response& res) {
    if (++polls == 1) {
      res.status = 503;
      res.set_content(R"({"error": "full\u001b]0;retitled\u0007"})", "application/json");
    } else {
      res.set_content(R"({"id": 7, "state": "done", "frames": 0, "frames_done": 0, "rows_done": 0, "rows_total": 0,
                          "resumed_rows": 0, "rerendered_rows": 0})",
                      "application/json");
    }
  });
  const int port = busy.bind_to_any_port("127.0.0.1");
  REQUIRE(port > 0);
  std::thread serving([&busy] { busy.listen_after_bind(); });
  const std::filesystem::path dir = test::scratch_dir("fetch-busy-escaped");
  const test::CommandResult r =
      test::run_command("timeout 60 " + test::rayfarm_exe() + " fetch 7 --wait -o " + (dir / "out.png").string() +
                        " --broker http://127.0.0.1:" + std::to_string(port));
  CAPTURE(r.output);
  CHECK(r.output.find("is busy (HTTP 503): full\\x1b]0;retitled\\x07; waiting up to 600 s for it") !=
        std::string::npos);
  CHECK(r.output.find('\x1b') == std::string::npos);
  CHECK(polls >= 2);
  busy.stop();
  serving.join();
  std::filesystem::remove_all(dir);
}

TEST_CASE("http api: another program on the broker's port is named as such, not by a JSON parser's complaint") {
  httplib::Server other;
  other.Get("/api/jobs", [](const httplib::Request&, httplib::Response& res) {
    res.set_content("<html><body>Welcome to Jenkins</body></html>\n", "text/html");
  });
  other.Get("/api/jobs/1", [](const httplib::Request&, httplib::Response& res) {
    res.set_content(R"({"id": 1, "name": "nightly", "state": "running"})", "application/json");
  });
  other.Get("/api/jobs/2", [](const httplib::Request&, httplib::Response& res) {
    // Every count of a job status, but an error that is no text.
    res.set_content(R"({"id": 2, "state": "failed", "frames": 1, "frames_done": 0, "rows_done": 0, "rows_total": 4,
                        "resumed_rows": 0, "rerendered_rows": 0, "error": {"code": 7}})",
                    "application/json");
  });
  other.Post("/api/jobs", [](const httplib::Request&, httplib::Response& res) {
    res.status = 413;
    res.set_content("<html><head><title>413 Request Entity Too Large</title></head></html>\n", "text/html");
  });
  const int port = other.bind_to_any_port("127.0.0.1");
  REQUIRE(port > 0);
  std::thread serving([&other] { other.listen_after_bind(); });
  const std::string url = "http://127.0.0.1:" + std::to_string(port);
  ApiClient client(url);
  CHECK_THROWS_WITH(client.list(), (url + "/api/jobs answered something other than JSON: is " + url +
                                    " a rayfarm broker?").c_str());
  CHECK_THROWS_WITH(client.status(1), (url + "/api/jobs/1 answered JSON that is no job status: is " + url +
                                       " a rayfarm broker?").c_str());
  // Was the JSON library's "type must be string" once the status was printed.
  CHECK_THROWS_WITH(client.status(2), (url + "/api/jobs/2 answered JSON that is no job status: is " + url +
                                       " a rayfarm broker?").c_str());
  CHECK_THROWS_WITH_AS(client.submit(tiny_submission(1)),
                       doctest::Contains(("submit: HTTP 413 Payload Too Large from " + url + ", not the").c_str()),
                       ApiError);
  other.stop();
  serving.join();
}

TEST_CASE("http api: a broker that takes the connection and never answers (stopped) is named in seconds, not minutes" *
          doctest::timeout(90)) {
  // No one accepts, as for a broker stopped with SIGSTOP.
  std::string url;
  const int fd = silent_listener(url);
  const auto start = std::chrono::steady_clock::now();
  // Unreachable, not refused: `fetch --wait` waits it out as it waits out a restart.
  CHECK_THROWS_WITH_AS(ApiClient(url).status(1), doctest::Contains((url + " did not answer within").c_str()),
                       BrokerUnreachable);
  CHECK(std::chrono::steady_clock::now() - start < std::chrono::seconds(30));
  // A cancel sent may still be carried out when the broker answers late: not "try again".
  CHECK_THROWS_WITH_AS(ApiClient(url).cancel(1), doctest::Contains("; the cancel may still take effect when it answers"),
                       BrokerUnreachable);
  ::close(fd);
}

namespace {

// `output` without the notices of a long wait (service/wait_notice.h): a
// --timeout of 1 s gives one at 0.5 s of each wait, which a loaded machine
// may not get to before the wait runs out. The cases below that hold the
// answer until its notice has come check them.
std::string without_waiting_notices(const std::string& output) {
  std::istringstream lines(output);
  std::string rest;
  for (std::string line; std::getline(lines, line);)
    if (line.rfind("rayfarm: waiting for the broker at ", 0) != 0) rest += line + "\n";
  return rest;
}

// What a command wrote to `path` so far (its stderr), "" before it has.
std::string written_so_far(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

// The shell command that runs `rayfarm ARGS` with its stderr to `stderr_path`:
// run_command's output is then stdout alone, what a script captures.
std::string stdout_only(const std::string& args, const std::string& stderr_path) {
  return "(" + test::rayfarm_exe() + " " + args + " 2>'" + stderr_path + "')";
}

// Until `path` holds `text`, up to a minute (a hang guard, no timing).
void await_text(const std::string& path, const std::string& text) {
  for (int i = 0; i < 1200 && written_so_far(path).find(text) == std::string::npos; ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
}

const char* const kQueuedSeven = R"({"id": 7, "state": "queued", "frames": 1, "frames_done": 0, "rows_done": 0,
                                     "rows_total": 24, "resumed_rows": 0, "rerendered_rows": 0})";

}  // namespace

TEST_CASE("submit --timeout: a broker that takes the connection and never answers is sent the submission again at"
          " once, each attempt said, and the key named, and status, cancel and fetch keep the timeout too" *
          doctest::timeout(60)) {
  // No one accepts, as for a broker stopped with SIGSTOP: each attempt took
  // the 300 s a submission's answer is given, and a second more before the
  // next, some 20 minutes without a word before the first retry was said.
  std::string url;
  const int fd = silent_listener(url);
  const std::string scene = fresh_dir("client-timeout") + ".nff";
  write_text_file(scene, test::tiny_scene(0));
  const std::string silent = "rayfarm: the broker at " + url +
                             " did not answer within 1 s (is it stopped or hung? --timeout SECONDS sets the wait)";
  const std::string may = "; the submit may still take effect when it answers: see rayfarm status";
  const auto r = test::run_command(test::rayfarm_exe() + " submit --broker " + url + " --timeout 1 " +
                                   "--idempotency-key nightly-7 " + scene);
  CHECK(r.exit_code == 1);
  std::string said;
  for (int attempt = 2; attempt <= 4; ++attempt)
    said += silent + may + "; sending it again now with the same Idempotency-Key, which makes no second job (attempt " +
            std::to_string(attempt) + " of 4)\n";
  said += silent + may + " (sent 4 times; to try again without a second job: --idempotency-key nightly-7)\n";
  CHECK(without_waiting_notices(r.output) == said);
  for (const std::string& command :
       std::vector<std::string>{"status 7", "cancel 7", "fetch 7 -o " + scene + ".png"}) {
    CAPTURE(command);
    const auto other = test::run_command(test::rayfarm_exe() + " " + command + " --broker " + url + " --timeout 1");
    CHECK(other.exit_code == 1);
    CHECK_MESSAGE(without_waiting_notices(other.output).rfind(silent, 0) == 0, other.output);
  }
  const std::pair<std::string, std::string> refused[] = {
      {"0", "--timeout: expected a value in [1, 86400], found 0"},
      {"86401", "--timeout: expected a value in [1, 86400], found 86401"},
      {"1.5", "--timeout: expected a whole number, found 1.5"}};
  for (const auto& [value, reason] : refused) {
    CAPTURE(value);
    const auto bad = test::run_command(test::rayfarm_exe() + " status --broker " + url + " --timeout " + value);
    CHECK(bad.exit_code == 1);
    CHECK(bad.output == "rayfarm: " + reason + "\n");
  }
  ::close(fd);
}

TEST_CASE("submit, status, cancel: an answer long in coming is said on stderr while awaited, stdout as ever, and"
          " a quick answer says nothing" * doctest::timeout(200)) {
  // The broker took the connection and said nothing for the whole wait, 5
  // minutes for a submission (20 with its resending), and the user saw nothing.
  const std::string dir = fresh_dir("waiting-notice");
  fs::create_directories(dir);
  const std::string scene = dir + "/a.nff", said = dir + "/stderr.txt";
  write_text_file(scene, test::tiny_scene(0));
  std::atomic<bool> held{true};
  const std::string notice = "rayfarm: waiting for the broker at ";
  // A busy broker (writing a big job to its state folder, say): it answers
  // once the client has said that it waits, while `held`.
  const auto answering = [&](std::string body) {
    return [&, body](const httplib::Request&, httplib::Response& res) {
      if (held) await_text(said, notice);
      res.set_content(body, "application/json");
    };
  };
  std::string cancelled = kQueuedSeven;
  cancelled.replace(cancelled.find("queued"), 6, "cancelled");
  httplib::Server broker;
  broker.Post("/api/jobs", answering(kQueuedSeven));
  broker.Get("/api/jobs/7", answering(kQueuedSeven));
  broker.Post("/api/jobs/7/cancel", answering(cancelled));
  const int port = broker.bind_to_any_port("127.0.0.1");
  REQUIRE(port > 0);
  std::thread serving([&broker] { broker.listen_after_bind(); });
  const std::string url = "http://127.0.0.1:" + std::to_string(port);
  struct Case {
    std::string args, printed, waiting;
  };
  const Case cases[] = {
      {"submit " + scene, "7\n", "the submission (5 s so far; giving up after 20 s, then sending it again)"},
      {"status 7", "7      queued    frames 0/1  rows 0/24  resumed 0  re-rendered 0\n",
       "job 7's status (5 s so far; giving up after 20 s)"},
      {"cancel 7", "7      cancelled frames 0/1  rows 0/24  resumed 0  re-rendered 0\n",
       "the cancel of job 7 (5 s so far; giving up after 20 s)"}};
  for (const bool hold : {true, false}) {
    held = hold;
    for (const Case& c : cases) {
      CAPTURE(hold);
      CAPTURE(c.args);
      fs::remove(said);
      const auto r = test::run_command(stdout_only(c.args + " --broker " + url + " --timeout 20", said));
      CHECK(r.exit_code == 0);
      CHECK(r.output == c.printed);  // what a script reads is as before
      const std::string err = written_so_far(said);
      if (hold) {
        // Once; a loaded machine may get to the next mark, 10 s, before the answer.
        CHECK_MESSAGE(err.rfind(notice + url + " to answer " + c.waiting + "\n", 0) == 0, err);
        CHECK(without_waiting_notices(err) == "");
      } else {
        CHECK(err == "");
      }
    }
  }
  broker.stop();
  serving.join();
}

TEST_CASE("fetch --wait: a broker unreachable for long is said again at growing intervals, not only at first" *
          doctest::timeout(120)) {
  // It was said once, "waiting up to 600 s for it", then 10 minutes of silence.
  const std::string dir = fresh_dir("waiting-reminder");
  fs::create_directories(dir);
  const std::string said = dir + "/stderr.txt";
  std::atomic<bool> busy{true};
  std::string cancelled = kQueuedSeven;
  cancelled.replace(cancelled.find("queued"), 6, "cancelled");
  httplib::Server broker;
  broker.Get("/api/jobs/7", [&](const httplib::Request&, httplib::Response& res) {
    // At its connection limit (503), until the client has said it still waits.
    busy = busy && written_so_far(said).find("still waiting") == std::string::npos;
    if (busy) {
      res.status = 503;
      res.set_content(R"({"error": "too many connections"})", "application/json");
    } else {
      res.set_content(cancelled, "application/json");
    }
  });
  const int port = broker.bind_to_any_port("127.0.0.1");
  REQUIRE(port > 0);
  std::thread serving([&broker] { broker.listen_after_bind(); });
  const std::string url = "http://127.0.0.1:" + std::to_string(port);
  const auto r = test::run_command(stdout_only("fetch 7 --wait -o " + dir + "/out.png --broker " + url, said));
  CHECK(r.exit_code == 1);
  CHECK(r.output == "");
  std::istringstream lines(written_so_far(said));
  std::vector<std::string> err;
  for (std::string line; std::getline(lines, line);) err.push_back(line);
  REQUIRE(err.size() == 4);
  CHECK(err[0] == "rayfarm: the broker at " + url + " is busy (HTTP 503): too many connections; waiting up to 600 s for it");
  // How long so far is as long as it was: 5 s, or more on a loaded machine.
  const std::string still = "rayfarm: still waiting for the broker at " + url + " (";
  CHECK_MESSAGE(err[1].rfind(still, 0) == 0, err[1]);
  const std::string tail = " s so far; giving up after 600 s)";
  const bool ends_so = err[1].size() > tail.size() && err[1].compare(err[1].size() - tail.size(), tail.size(), tail) == 0;
  CHECK_MESSAGE(ends_so, err[1]);
  CHECK(err[2] == "rayfarm: the broker at " + url + " answers again");
  CHECK(err[3] == "rayfarm: job 7 is cancelled");
  broker.stop();
  serving.join();
}

TEST_CASE("http api: a broker that dies after reading a submission or cancel says it may have taken effect" *
          doctest::timeout(60)) {
  // A listener that reads each request and closes unanswered, as a broker
  // killed between storing a job and answering for it does.
  std::string url;
  const int fd = silent_listener(url);
  std::thread dying([fd] {
    for (int i = 0; i < 3; ++i) {
      const int c = ::accept(fd, nullptr, nullptr);
      if (c < 0) return;
      read_answer(c, 300);  // the whole request, then closed
    }
  });
  // Was "cannot reach the broker at URL (Read)": sent again, the job ran twice.
  CHECK_THROWS_WITH_AS(ApiClient(url).submit(tiny_submission(1)),
                       ("the broker at " + url + " closed the connection before answering (did it stop or restart?); "
                        "the submit may have taken effect: see rayfarm status").c_str(),
                       BrokerUnreachable);
  CHECK_THROWS_WITH_AS(ApiClient(url).cancel(1), doctest::Contains("; the cancel may have taken effect"),
                       BrokerUnreachable);
  // A status changes nothing: unreachable, for `fetch --wait` to wait out.
  CHECK_THROWS_WITH_AS(ApiClient(url).status(1),
                       ("the broker at " + url + " closed the connection before answering (did it stop or restart?)")
                           .c_str(),
                       BrokerUnreachable);
  dying.join();
  ::close(fd);
}

TEST_CASE("http api: an unreachable broker is told apart from a refusal") {
  ApiClient client("http://127.0.0.1:1");
  CHECK_THROWS_AS(client.list(), BrokerUnreachable);
  CHECK(frame_output_path("out/anim.png", 3, 12) == "out/anim-0003.png");
  CHECK(frame_output_path("out.v2/anim", 1, 2) == "out.v2/anim-0001");
  CHECK(frame_output_path("still.exr", 1, 1) == "still.exr");
}
