// The HTTP API on the wire, over raw sockets (127.0.0.1, port 0 read back):
// what RFC 9110/9112 ask of heads, bodies, ranges, versions and connections,
// and the limits that keep a hostile client from holding the service.
#include <doctest/doctest.h>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <mutex>
#include <filesystem>
#include <sstream>
#include <thread>
#include <vector>

#include <httplib.h>

#include "service/api_client.h"
#include "service/http_api.h"
#include "service/http_connection.h"
#include "status/status_board.h"
#include "tests/http_peers.h"
#include "tests/service_scenes.h"
#include "tests/test_files.h"
#include "tracer/error.h"
#include "tracer/text_file.h"

using namespace rayfarm;
using namespace rayfarm::http_test;
namespace fs = std::filesystem;

TEST_CASE("http api: a header line over 8 KiB is refused 431 with a reason, not 400") {
  JobService jobs(fresh_dir("long-header"));
  HttpApi api(jobs, any_port());
  const std::string answer = exchange_until_closed(
      port_of(api), "GET /api/jobs HTTP/1.1\r\nHost: x\r\nX-Big: " + std::string(9000, 'a') + "\r\n\r\n", 3000);
  CHECK(answer.rfind("HTTP/1.1 431", 0) == 0);
  CHECK(answer.find(R"("error": "request header line longer than 8192 bytes")") != std::string::npos);
  // Refused as soon as the line passes the limit, not kept until it ends.
  const int fd = connect_to(port_of(api));
  const std::string endless = "GET /api/jobs HTTP/1.1\r\nX-Big: " + std::string(100000, 'a');
  ::send(fd, endless.data(), endless.size(), MSG_NOSIGNAL);
  pollfd p{fd, POLLIN, 0};
  char buf[64];
  REQUIRE(::poll(&p, 1, 3000) == 1);
  CHECK(::recv(fd, buf, sizeof buf, 0) > 12);
  CHECK(std::string(buf, 12) == "HTTP/1.1 431");
  ::close(fd);
  const std::string fits = raw_exchange(
      port_of(api), "GET /api/jobs HTTP/1.1\r\nHost: x\r\nX-Big: " + std::string(8000, 'a') + "\r\n\r\n", 3000);
  CHECK(fits.rfind("HTTP/1.1 200", 0) == 0);
}

TEST_CASE("http api: pipelined requests are each answered, and after a refusal the connection closes saying so") {
  JobService jobs(fresh_dir("pipelined"));
  HttpApi api(jobs, any_port());
  const std::string list = "GET /api/jobs HTTP/1.1\r\nHost: x\r\n\r\n";
  const std::string last = "GET /api/jobs HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n";
  const std::string both = exchange_until_closed(port_of(api), list + last, 1500);
  CHECK(count_of(both, "HTTP/1.1 200 OK\r\n") == 2);
  // After a refusal the rest may be the refused request's own body or head:
  // the connection ends, and the answer says so, within the keep-alive's 2 s.
  for (const std::string& refused :
       {std::string("GET /nothing HTTP/1.1\r\nHost: x\r\n\r\n"), std::string("GARBAGE\r\n\r\n"),
        std::string("PUT /api/jobs HTTP/1.1\r\nHost: x\r\nContent-Length: 2\r\n\r\n{}"),
        std::string("POST /api/jobs HTTP/1.1\r\nHost: x\r\n\r\n")}) {
    CAPTURE(refused);
    const std::string answer = exchange_until_closed(port_of(api), refused + list, 1500);
    CHECK(count_of(answer, "HTTP/1.1 ") == 1);
    CHECK(answer.find("\r\nConnection: close\r\n") != std::string::npos);
  }
}

TEST_CASE("http api: a GET's body is not read as the connection's next request, its answer closes instead") {
  JobService jobs(fresh_dir("get-body"));
  HttpApi api(jobs, any_port());
  // httplib reads no GET body: its bytes were parsed as a next request, here
  // one for a missing path, answered 404 after the 200.
  const std::string hidden = "GET /api/nothing HTTP/1.1\r\nHost: y\r\n\r\n";
  const std::string sized = exchange_until_closed(
      port_of(api),
      "GET /api/jobs HTTP/1.1\r\nHost: x\r\nContent-Length: " + std::to_string(hidden.size()) + "\r\n\r\n" + hidden,
      3000);
  CHECK(sized.rfind("HTTP/1.1 200", 0) == 0);
  CHECK(count_of(sized, "HTTP/1.1 ") == 1);
  CHECK(sized.find("\r\nConnection: close\r\n") != std::string::npos);
  std::ostringstream size;
  size << std::hex << hidden.size();
  const std::string chunked = exchange_until_closed(port_of(api),
                                                    "GET /api/jobs HTTP/1.1\r\nHost: x\r\nTransfer-Encoding: chunked\r\n\r\n" +
                                                        size.str() + "\r\n" + hidden + "\r\n0\r\n\r\n",
                                                    3000);
  CHECK(chunked.rfind("HTTP/1.1 200", 0) == 0);
  CHECK(count_of(chunked, "HTTP/1.1 ") == 1);
  // A GET without a body keeps its connection.
  const std::string plain = raw_exchange(port_of(api), "GET /api/jobs HTTP/1.1\r\nHost: x\r\nContent-Length: 0\r\n\r\n", 1500);
  CHECK(plain.find("Keep-Alive: ") != std::string::npos);
}

TEST_CASE("http api: a transfer coding other than chunked is refused 501 at once, not read until the client closes") {
  JobService jobs(fresh_dir("transfer-coding"));
  HttpApi api(jobs, any_port());
  // Before, the body was read until the client closed, and refused 400
  // after the read timeout (the 2 s wait here ended with nothing).
  const std::string gzip = exchange_until_closed(
      port_of(api), "POST /api/jobs HTTP/1.1\r\nHost: x\r\nTransfer-Encoding: gzip\r\n\r\nabc", 2000);
  CHECK(gzip.rfind("HTTP/1.1 501", 0) == 0);
  CHECK(gzip.find(R"("error": "Transfer-Encoding: only chunked is supported, found 'gzip'")") != std::string::npos);
  CHECK(gzip.find("\r\nConnection: close\r\n") != std::string::npos);
  const std::string layered = exchange_until_closed(
      port_of(api), "POST /api/jobs HTTP/1.1\r\nHost: x\r\nTransfer-Encoding: gzip, chunked\r\n\r\n3\r\nabc\r\n", 2000);
  CHECK(layered.rfind("HTTP/1.1 501", 0) == 0);
  // Chunked, in any case, is still read.
  const std::string chunked = exchange_until_closed(
      port_of(api),
      "POST /api/jobs HTTP/1.1\r\nHost: x\r\nConnection: close\r\nContent-Type: application/json\r\n"
      "Transfer-Encoding: Chunked\r\n\r\n2\r\n{}\r\n0\r\n\r\n",
      2000);
  CHECK(chunked.rfind("HTTP/1.1 400", 0) == 0);
  CHECK(chunked.find("scenes") != std::string::npos);
}

TEST_CASE("http api: a request with both Transfer-Encoding and Content-Length is refused 400 and its connection closed") {
  JobService jobs(fresh_dir("both-lengths"));
  HttpApi api(jobs, any_port());
  const uint64_t id = ApiClient(api.address()).submit(tiny_submission(1));
  // Before, the chunked body was read, the length ignored, the job
  // cancelled, and the bytes after the chunks served as a next request: where
  // a proxy in front reads the length instead, that is a request smuggled
  // past it (RFC 9112 6.3).
  const std::string answer = exchange_until_closed(
      port_of(api),
      "POST /api/jobs/" + std::to_string(id) +
          "/cancel HTTP/1.1\r\nHost: x\r\nContent-Length: 5\r\n"
          "Transfer-Encoding: chunked\r\n\r\n0\r\n\r\nGET /api/jobs HTTP/1.1\r\nHost: x\r\n\r\n",
      3000);
  CHECK(jobs.status(id)["state"] == "queued");
  CHECK(answer.rfind("HTTP/1.1 400", 0) == 0);
  CHECK(answer.find(R"("error": "Transfer-Encoding and Content-Length given together)") != std::string::npos);
  CHECK(answer.find("\r\nConnection: close\r\n") != std::string::npos);
  CHECK(count_of(answer, "HTTP/1.1 ") == 1);
}

TEST_CASE("http api: a method no one knows is refused 501 Not Implemented, a broken request line still 400") {
  JobService jobs(fresh_dir("unknown-method"));
  HttpApi api(jobs, any_port());
  // Was 400 "malformed HTTP request" (RFC 9110 9.1: 501).
  const std::string foo = exchange_until_closed(port_of(api), "FOO /api/jobs HTTP/1.1\r\nHost: x\r\n\r\n", 2000);
  CHECK(foo.rfind("HTTP/1.1 501", 0) == 0);
  CHECK(foo.find(R"x("error": "method FOO not implemented (docs/api.md lists the methods of each path)")x") !=
        std::string::npos);
  CHECK(foo.find("\r\nConnection: close\r\n") != std::string::npos);
  const std::string broken = exchange_until_closed(port_of(api), "FOO /api/jobs\r\nHost: x\r\n\r\n", 2000);
  CHECK(broken.rfind("HTTP/1.1 400", 0) == 0);
  const std::string garbage = exchange_until_closed(port_of(api), "F(O) /api/jobs HTTP/1.1\r\nHost: x\r\n\r\n", 2000);
  CHECK(garbage.rfind("HTTP/1.1 400", 0) == 0);
}

TEST_CASE("http api: an answer that closes its connection does not also offer to keep it alive") {
  JobService jobs(fresh_dir("close-no-keep-alive"));
  HttpApi api(jobs, any_port());
  for (const std::string& closing :
       {std::string("GET /nothing HTTP/1.1\r\nHost: x\r\n\r\n"), std::string("GARBAGE\r\n\r\n"),
        std::string("PUT /api/jobs HTTP/1.1\r\nHost: x\r\nContent-Length: 2\r\n\r\n{}"),
        std::string("POST /api/jobs HTTP/1.1\r\nHost: x\r\nContent-Length: 1\r\n\r\n{"),
        std::string("GET /api/jobs HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n")}) {
    CAPTURE(closing);
    const std::string answer = exchange_until_closed(port_of(api), closing, 1500);
    CHECK(answer.find("\r\nConnection: close\r\n") != std::string::npos);
    CHECK(answer.find("Keep-Alive") == std::string::npos);
  }
  // Once, though the client asked to close too (it was sent twice).
  const std::string asked = exchange_until_closed(
      port_of(api), "GET /nothing HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n", 1500);
  CHECK(asked.rfind("HTTP/1.1 404", 0) == 0);
  CHECK(count_of(asked, "\r\nConnection: ") == 1);
  // A kept connection still says for how long.
  const std::string kept = raw_exchange(port_of(api), "GET /api/jobs HTTP/1.1\r\nHost: x\r\n\r\n", 1500);
  CHECK(kept.find("\r\nKeep-Alive: timeout=2") != std::string::npos);
}

TEST_CASE("http api: clients sending their request heads a byte at a time do not hold back an answer" *
          doctest::timeout(120)) {
  JobService jobs(fresh_dir("slow-heads"));
  HttpApi api(jobs, any_port());
  std::vector<int> slow;  // more than the server's 64 threads
  for (int i = 0; i < 70; ++i) {
    slow.push_back(connect_to(port_of(api)));
    ::send(slow.back(), "GET /api/jobs HTTP/1.1\r\n", 25, MSG_NOSIGNAL);
  }
  std::atomic<bool> answered{false};
  std::thread trickle([&] {  // a header byte a second from each, well within httplib's 5 s for each read
    for (int s = 0; s < 20 && !answered; ++s) {
      std::this_thread::sleep_for(std::chrono::seconds(1));
      for (int fd : slow) ::send(fd, "X", 1, MSG_NOSIGNAL);
    }
  });
  // Answered at once: a head still arriving holds no thread (without the
  // head's deadline no answer came within 20 s, with it not before 5 s).
  httplib::Client client(api.address());
  client.set_read_timeout(15);
  const auto r = client.Get("/api/jobs");
  // A slow head is told why it was refused, once its time is up.
  pollfd p{slow.front(), POLLIN, 0};
  CHECK(::poll(&p, 1, 10000) == 1);
  answered = true;
  trickle.join();
  CHECK(r);
  if (r) CHECK(r->status == 200);
  char buf[64] = "";
  CHECK(::recv(slow.front(), buf, sizeof buf - 1, MSG_DONTWAIT) > 0);
  CHECK(std::string(buf).rfind("HTTP/1.1 408", 0) == 0);
  for (int fd : slow) ::close(fd);
}

TEST_CASE("http api: a body trickling in, each byte within the read timeout, is refused 408, not waited for" *
          doctest::timeout(60)) {
  JobService jobs(fresh_dir("slow-body"));
  HttpApi api(jobs, any_port());
  const int fd = connect_to(port_of(api));
  const std::string head =
      "POST /api/jobs HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\nContent-Length: 1000\r\n\r\n";
  REQUIRE(::send(fd, head.data(), head.size(), MSG_NOSIGNAL) == static_cast<ssize_t>(head.size()));
  // A byte a second: before, each read waited its 5 s and the thread waited
  // the whole 1000 s; now the body's deadline passes within seconds.
  // The answer is read to the connection's close: its head and body may
  // come in separate segments.
  std::string answer;
  pollfd p{fd, POLLIN, 0};
  bool closed = false;
  for (int s = 0; s < 20 && !closed; ++s) {
    if (answer.empty()) ::send(fd, " ", 1, MSG_NOSIGNAL);
    while (!closed && ::poll(&p, 1, 1000) == 1) {
      char buf[512];
      const ssize_t n = ::recv(fd, buf, sizeof buf, 0);
      closed = n <= 0;
      if (n > 0) answer.append(buf, static_cast<size_t>(n));
    }
  }
  ::close(fd);
  CHECK(answer.rfind("HTTP/1.1 408", 0) == 0);
  CHECK(answer.find("\r\nConnection: close\r\n") != std::string::npos);
  CHECK(answer.find(R"("error": "request body arriving slower than 64 KiB/s")") != std::string::npos);
  // A body that arrives, in pieces, is read whole.
  const int whole = connect_to(port_of(api));
  const std::string job = "{\"scenes\": []}";
  const std::string post = "POST /api/jobs HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\nContent-Length: " +
                           std::to_string(job.size()) + "\r\n\r\n";
  ::send(whole, post.data(), post.size(), MSG_NOSIGNAL);
  std::this_thread::sleep_for(std::chrono::seconds(2));
  ::send(whole, job.data(), job.size(), MSG_NOSIGNAL);
  pollfd q{whole, POLLIN, 0};
  char buf[64] = "";
  REQUIRE(::poll(&q, 1, 5000) == 1);
  CHECK(::recv(whole, buf, sizeof buf - 1, 0) > 12);
  CHECK(std::string(buf).rfind("HTTP/1.1 400", 0) == 0);  // read whole, then judged: no scenes
  ::close(whole);
}

TEST_CASE("http api: a body announced over the limit is refused 413 at once, not read to its end first") {
  JobService jobs(fresh_dir("announced-length"));
  HttpApi api(jobs, any_port());
  // Before, the service read (and dropped) every announced byte before
  // answering: a client sending none was told after the 5 s read timeout,
  // one sending them kept a thread reading as long as it went on.
  const std::string huge = exchange_until_closed(
      port_of(api), "POST /api/jobs HTTP/1.1\r\nHost: x\r\nContent-Length: 999999999999\r\n\r\n{", 2000);
  CHECK(huge.rfind("HTTP/1.1 413", 0) == 0);
  CHECK(huge.find(R"("error": "request body larger than 512 MiB")") != std::string::npos);
  const std::string form = exchange_until_closed(
      port_of(api),
      "POST /api/jobs HTTP/1.1\r\nHost: x\r\nContent-Type: application/x-www-form-urlencoded\r\n"
      "Content-Length: 100000\r\n\r\n{",
      2000);
  CHECK(form.rfind("HTTP/1.1 413", 0) == 0);
  // Was 413 "larger than 512 MiB" (httplib read -1 as the largest number).
  const std::string negative =
      exchange_until_closed(port_of(api), "POST /api/jobs HTTP/1.1\r\nHost: x\r\nContent-Length: -1\r\n\r\n{", 2000);
  CHECK(negative.rfind("HTTP/1.1 400", 0) == 0);
  CHECK(negative.find(R"("error": "Content-Length: expected a number of bytes, found '-1'")") != std::string::npos);
  const std::string twice = exchange_until_closed(
      port_of(api), "POST /api/jobs HTTP/1.1\r\nHost: x\r\nContent-Length: 2\r\nContent-Length: 1\r\n\r\n{}", 2000);
  CHECK(twice.rfind("HTTP/1.1 400", 0) == 0);
  CHECK(twice.find(R"("error": "Content-Length: given twice, as 2 and 1")") != std::string::npos);
  // A body within the limit is still read and judged.
  const std::string fits =
      raw_exchange(port_of(api), "POST /api/jobs HTTP/1.1\r\nHost: x\r\nContent-Length: 2\r\n\r\n{}", 2000);
  CHECK(fits.rfind("HTTP/1.1 400", 0) == 0);
  CHECK(fits.find("scenes") != std::string::npos);
}

TEST_CASE("http api: a chunked body is held to the payload limit, as a body with a length is") {
  // The server of the API with a limit small enough to pass in a test (the API's is 512 MiB).
  HttpServer server;
  server.set_payload_max_length(1000);
  std::atomic<size_t> received{0};
  server.Post("/x", [&](const httplib::Request& req, httplib::Response& res) {
    received = req.body.size();
    res.set_content("taken", "text/plain");
  });
  std::atomic<RequestFault> fault{RequestFault::none};
  server.set_error_handler([&](const httplib::Request&, httplib::Response&) {
    fault = HttpServer::request_fault();
    HttpServer::close_after_response();
  });
  const int port = server.bind_to_any_port("127.0.0.1");
  std::thread serving([&] { server.listen_after_bind(); });
  while (!server.is_running()) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  const auto chunked = [&](size_t chunks) {
    std::string request = "POST /x HTTP/1.1\r\nHost: x\r\nConnection: close\r\nTransfer-Encoding: chunked\r\n\r\n";
    for (size_t i = 0; i < chunks; ++i) request += "64\r\n" + std::string(100, 'a') + "\r\n";
    return exchange_until_closed(port, request + "0\r\n\r\n", 3000);
  };
  // Before, httplib kept a chunked body of any size (700 MiB sent to the API
  // were read whole into memory before being judged).
  const std::string over = chunked(20);
  CHECK(over.rfind("HTTP/1.1 200", 0) != 0);
  CHECK(fault == RequestFault::body_too_long);
  CHECK(received == 0);
  fault = RequestFault::none;
  const std::string within = chunked(5);
  CHECK(within.rfind("HTTP/1.1 200", 0) == 0);
  CHECK(received == 500);
  CHECK(fault == RequestFault::none);
  server.stop();
  serving.join();
}


TEST_CASE("http api: connections past the limit, in all or from one address, are answered 503 and logged once") {
  JobService jobs(fresh_dir("connection-limit"));
  HttpOptions options = any_port();
  options.max_connections = 4;  // 2 from one address
  std::mutex log_mutex;
  std::vector<std::string> lines;
  HttpApi api(jobs, options, nullptr, [&](const std::string& line) {
    std::lock_guard<std::mutex> lock(log_mutex);
    lines.push_back(line);
  });
  const int port = port_of(api);
  // Before, every connection was taken: a client opening thousands ran the
  // broker out of files (a job's folder could not be written, 500).
  std::vector<int> held = {connect_from("127.0.0.2", port), connect_from("127.0.0.2", port)};
  const std::string one_address = status_of_get(connect_from("127.0.0.2", port));
  CHECK(one_address.rfind("HTTP/1.1 503", 0) == 0);
  CHECK(one_address.find("\r\nConnection: close\r\n") != std::string::npos);
  CHECK(one_address.find(R"("error": "this address holds 2 connections to the service)") != std::string::npos);
  // Another address still gets in, until the total is reached.
  held.push_back(connect_from("127.0.0.3", port));
  CHECK(status_of_get(connect_from("127.0.0.4", port)).rfind("HTTP/1.1 200", 0) == 0);
  held.push_back(connect_from("127.0.0.3", port));
  for (int i = 0; i < 5; ++i) {
    const std::string full = status_of_get(connect_from("127.0.0.4", port));
    CHECK(full.rfind("HTTP/1.1 503", 0) == 0);
    CHECK(full.find(R"("error": "the service has 4 connections open, the most it takes: retry later")") !=
          std::string::npos);
  }
  {
    std::lock_guard<std::mutex> lock(log_mutex);
    REQUIRE(lines.size() == 1);  // not one a refusal
    CHECK(lines[0] == "HTTP API: 2 connections open from 127.0.0.2, the most one address may hold (half of "
                      "--http-connections): new connections are answered 503 and closed");
  }
  // A connection closed gives its place back.
  ::close(held.back());
  held.pop_back();
  std::string again;
  for (int i = 0; i < 50 && again.rfind("HTTP/1.1 200", 0) != 0; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    again = status_of_get(connect_from("127.0.0.4", port));
  }
  CHECK(again.rfind("HTTP/1.1 200", 0) == 0);
  for (int fd : held) ::close(fd);
}

TEST_CASE("http api: bodies being received together are held to a budget, past it a request is answered 503") {
  JobService jobs(fresh_dir("body-budget"));
  HttpOptions options = any_port();
  options.body_budget = 200000;
  HttpApi api(jobs, options);
  const int port = port_of(api);
  // Before, each body was held to 512 MiB alone: many at once took memory without bound.
  const int slow = connect_to(port);
  const std::string head = "POST /api/jobs HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\n";
  const std::string first = head + "Content-Length: 150000\r\n\r\n{";
  REQUIRE(::send(slow, first.data(), first.size(), 0) == static_cast<ssize_t>(first.size()));
  std::this_thread::sleep_for(std::chrono::milliseconds(200));  // its head taken, its body awaited
  const std::string told = exchange_until_closed(port, head + "Content-Length: 60000\r\n\r\n{", 2000);
  CHECK(told.rfind("HTTP/1.1 503", 0) == 0);
  CHECK(told.find("\r\nRetry-After: 2\r\n") != std::string::npos);
  CHECK(told.find(R"("error": "the service is receiving other requests' bodies)") != std::string::npos);
  // A chunked body, its length not told, is stopped once it passes what is left.
  std::string chunked = head + "Transfer-Encoding: chunked\r\n\r\n";
  for (int i = 0; i < 30; ++i) chunked += "1000\r\n" + std::string(4096, ' ') + "\r\n";
  const std::string stopped = exchange_until_closed(port, chunked + "0\r\n\r\n", 3000);
  CHECK(stopped.rfind("HTTP/1.1 503", 0) == 0);
  // Within what is left, a body is read and judged.
  const std::string fits = exchange_until_closed(port, head + "Content-Length: 2\r\nConnection: close\r\n\r\n{}", 2000);
  CHECK(fits.rfind("HTTP/1.1 400", 0) == 0);
  // Once the first is answered its share is free again.
  const std::string rest = std::string(149999, ' ');
  REQUIRE(::send(slow, rest.data(), rest.size(), 0) == static_cast<ssize_t>(rest.size()));
  pollfd p{slow, POLLIN, 0};
  CHECK(::poll(&p, 1, 3000) == 1);
  ::close(slow);
  std::string again;
  for (int i = 0; i < 50 && again.rfind("HTTP/1.1 400", 0) != 0; ++i) {
    if (i > 0) std::this_thread::sleep_for(std::chrono::milliseconds(20));
    again = exchange_until_closed(port, head + "Content-Length: 60000\r\nConnection: close\r\n\r\n{" +
                                            std::string(59999, ' '), 2000);
  }
  CHECK(again.rfind("HTTP/1.1 400", 0) == 0);
}

TEST_CASE("http api: a method no one knows is answered 501 with an Allow header, as a 405 is") {
  JobService jobs(fresh_dir("unknown-method-allow"));
  HttpApi api(jobs, any_port());
  // Before, the 501 named no methods at all.
  const std::string jobs_path = exchange_until_closed(port_of(api), "PROPFIND /api/jobs HTTP/1.1\r\nHost: x\r\n\r\n", 2000);
  CHECK(jobs_path.rfind("HTTP/1.1 501", 0) == 0);
  CHECK(jobs_path.find("\r\nAllow: GET, HEAD, POST, OPTIONS\r\n") != std::string::npos);
  const std::string cancel =
      exchange_until_closed(port_of(api), "BREW /api/jobs/%37/cancel?x=1 HTTP/1.1\r\nHost: x\r\n\r\n", 2000);
  CHECK(cancel.rfind("HTTP/1.1 501", 0) == 0);
  CHECK(cancel.find("\r\nAllow: POST, OPTIONS\r\n") != std::string::npos);
  // A path no route serves: the methods the service serves at all.
  const std::string nowhere = exchange_until_closed(port_of(api), "BREW /nowhere HTTP/1.1\r\nHost: x\r\n\r\n", 2000);
  CHECK(nowhere.rfind("HTTP/1.1 501", 0) == 0);
  CHECK(nowhere.find("\r\nAllow: GET, HEAD, POST, OPTIONS\r\n") != std::string::npos);
  const std::string put = exchange_until_closed(port_of(api), "PUT /api/jobs/7/cancel HTTP/1.1\r\nHost: x\r\n\r\n", 2000);
  CHECK(put.rfind("HTTP/1.1 405", 0) == 0);
  CHECK(put.find("\r\nAllow: POST, OPTIONS\r\n") != std::string::npos);
}

TEST_CASE("http api: a request head of many header lines, each within the limit, is refused 431 past 64 KiB") {
  JobService jobs(fresh_dir("long-head"));
  HttpApi api(jobs, any_port());
  // Before, every header line was kept however many came (42 MB in 3.5 s).
  std::string head = "GET /api/jobs HTTP/1.1\r\nHost: x\r\n";
  for (int i = 0; i < 100; ++i) head += "X-Pad-" + std::to_string(i) + ": " + std::string(1000, 'a') + "\r\n";
  const std::string answer = exchange_until_closed(port_of(api), head + "\r\n", 3000);
  CHECK(answer.rfind("HTTP/1.1 431", 0) == 0);
  CHECK(answer.find(R"("error": "request head (request line and headers) longer than 65536 bytes")") !=
        std::string::npos);
  // A head of many short lines within it is served.
  std::string many = "GET /api/jobs HTTP/1.1\r\nHost: x\r\nConnection: close\r\n";
  for (int i = 0; i < 1000; ++i) many += "X-" + std::to_string(i) + ": y\r\n";
  CHECK(exchange_until_closed(port_of(api), many + "\r\n", 3000).rfind("HTTP/1.1 200", 0) == 0);
}

TEST_CASE("http api: white space between a header's name and its colon is refused 400, nothing smuggled behind it") {
  JobService jobs(fresh_dir("header-name-space"));
  HttpApi api(jobs, any_port());
  // Before, "Transfer-Encoding : chunked" was no header httplib knew: the body
  // was read by the Content-Length (a proxy trimming the name reads it
  // chunked, and the GET behind it as a request of its own).
  const std::string smuggled = exchange_until_closed(
      port_of(api),
      "POST /api/jobs HTTP/1.1\r\nHost: x\r\nTransfer-Encoding : chunked\r\nContent-Length: 4\r\n\r\n0\r\n\r\n"
      "GET /api/jobs HTTP/1.1\r\nHost: x\r\n\r\n",
      2000);
  CHECK(smuggled.rfind("HTTP/1.1 400", 0) == 0);
  CHECK(smuggled.find(R"("error": "header 'Transfer-Encoding ': a header name is a token, without white space before its colon")") !=
        std::string::npos);
  CHECK(smuggled.find("\r\nConnection: close\r\n") != std::string::npos);
  CHECK(count_of(smuggled, "HTTP/1.1 ") == 1);
  const std::string host = exchange_until_closed(port_of(api), "GET /api/jobs HTTP/1.1\r\nHost\t: x\r\n\r\n", 2000);
  CHECK(host.rfind("HTTP/1.1 400", 0) == 0);
  CHECK(jobs.list().empty());
}

TEST_CASE("http api: Expect 100-continue is answered 100 only for a request that will be served") {
  JobService jobs(fresh_dir("expect-continue"));
  HttpApi api(jobs, any_port("secret"));
  const std::string head = "POST /api/jobs HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\nExpect: 100-continue\r\n";
  // Before, httplib said 100 Continue first, and the client began sending
  // the body of a request refused anyway.
  const std::string huge = exchange_until_closed(
      port_of(api), head + "Authorization: Bearer secret\r\nContent-Length: 999999999999\r\n\r\n", 2000);
  CHECK(huge.rfind("HTTP/1.1 413", 0) == 0);
  CHECK(huge.find("100 Continue") == std::string::npos);
  const std::string no_token = exchange_until_closed(port_of(api), head + "Content-Length: 2\r\n\r\n", 2000);
  CHECK(no_token.rfind("HTTP/1.1 401", 0) == 0);
  CHECK(no_token.find("100 Continue") == std::string::npos);
  // One that passes is told to go on, then answered once its body is in.
  const int fd = connect_to(port_of(api));
  const std::string ok_head = head + "Authorization: Bearer secret\r\nContent-Length: 2\r\n\r\n";
  REQUIRE(::send(fd, ok_head.data(), ok_head.size(), 0) == static_cast<ssize_t>(ok_head.size()));
  char buf[4096];
  pollfd p{fd, POLLIN, 0};
  REQUIRE(::poll(&p, 1, 2000) == 1);
  const ssize_t n = ::recv(fd, buf, sizeof buf, 0);
  CHECK(std::string(buf, static_cast<size_t>(std::max<ssize_t>(n, 0))) == "HTTP/1.1 100 Continue\r\n\r\n");
  REQUIRE(::send(fd, "{}", 2, 0) == 2);
  std::string answer;
  while (::poll(&p, 1, 2000) == 1) {
    const ssize_t got = ::recv(fd, buf, sizeof buf, 0);
    if (got <= 0) break;
    answer.append(buf, static_cast<size_t>(got));
    if (answer.find("}\n") != std::string::npos) break;
  }
  ::close(fd);
  CHECK(answer.rfind("HTTP/1.1 400", 0) == 0);
  CHECK(answer.find("scenes") != std::string::npos);
}

TEST_CASE("http api: a Range is served for one range of a GET's answer, an error or a POST's answer comes whole") {
  JobService jobs(fresh_dir("ranges"));
  HttpApi api(jobs, any_port());
  ApiClient(api.address()).submit(tiny_submission(1));
  const std::string whole = exchange_until_closed(port_of(api), "GET /api/jobs HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n", 2000);
  REQUIRE(whole.rfind("HTTP/1.1 200", 0) == 0);
  const std::string body = whole.substr(whole.find("\r\n\r\n") + 4);
  // One range of a GET's answer is still served.
  const std::string one = exchange_until_closed(
      port_of(api), "GET /api/jobs HTTP/1.1\r\nHost: x\r\nRange: bytes=0-4\r\nConnection: close\r\n\r\n", 2000);
  CHECK(one.find("\r\nContent-Range: bytes 0-4/") != std::string::npos);
  CHECK(one.rfind("HTTP/1.1 206", 0) == 0);  // was 200 with the part
  CHECK(one.substr(one.find("\r\n\r\n") + 4) == body.substr(0, 5));
  // Before, an error's JSON was cut to the range under its error status.
  const std::string missing = exchange_until_closed(
      port_of(api), "GET /api/jobs/9 HTTP/1.1\r\nHost: x\r\nRange: bytes=0-4\r\nConnection: close\r\n\r\n", 2000);
  CHECK(missing.rfind("HTTP/1.1 404", 0) == 0);
  CHECK(missing.find("Content-Range") == std::string::npos);
  CHECK(missing.find(R"("error": "no job 9")") != std::string::npos);
  const std::string cancel = exchange_until_closed(
      port_of(api),
      "POST /api/jobs/1/cancel HTTP/1.1\r\nHost: x\r\nRange: bytes=0-4\r\nContent-Length: 0\r\nConnection: close\r\n\r\n",
      2000);
  CHECK(cancel.rfind("HTTP/1.1 200", 0) == 0);
  CHECK(cancel.find(R"("state": "cancelled")") != std::string::npos);
  // Before, each of many ranges was served, the whole body again for each.
  std::string many = "GET /api/jobs HTTP/1.1\r\nHost: x\r\nConnection: close\r\nRange: bytes=0-";
  for (int i = 0; i < 1000; ++i) many += ",0-";
  const std::string answer = exchange_until_closed(port_of(api), many + "\r\n\r\n", 3000);
  CHECK(answer.rfind("HTTP/1.1 200", 0) == 0);
  CHECK(answer.size() < 2 * whole.size());
}

TEST_CASE("http api: a range past the end is answered 416 naming only the length, without a Content-Type") {
  JobService jobs(fresh_dir("range-416"));
  HttpApi api(jobs, any_port());
  const std::string whole = exchange_until_closed(port_of(api), "GET /api/jobs HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n", 2000);
  const std::string length = std::to_string(whole.size() - whole.find("\r\n\r\n") - 4);
  const std::string answer = exchange_until_closed(
      port_of(api), "GET /api/jobs HTTP/1.1\r\nHost: x\r\nRange: bytes=999999-\r\nConnection: close\r\n\r\n", 2000);
  CHECK(answer.rfind("HTTP/1.1 416", 0) == 0);
  // Before: "Content-Range: bytes 999999-2/3" and the JSON's Content-Type for no body.
  CHECK(answer.find("\r\nContent-Range: bytes */" + length + "\r\n") != std::string::npos);
  CHECK(count_of(answer, "Content-Range") == 1);
  CHECK(answer.find("Content-Type") == std::string::npos);
  CHECK(answer.find("\r\nContent-Length: 0\r\n") != std::string::npos);
}

TEST_CASE("http api: a Range header that cannot be read is refused 416 with a JSON reason naming it") {
  JobService jobs(fresh_dir("range-unreadable"));
  HttpApi api(jobs, any_port());
  for (const std::string range : {"bytes=abc", "bytes=5-1", "items=0-1"}) {
    CAPTURE(range);
    const std::string answer = exchange_until_closed(
        port_of(api), "GET /api/jobs HTTP/1.1\r\nHost: x\r\nRange: " + range + "\r\nConnection: close\r\n\r\n", 2000);
    CHECK(answer.rfind("HTTP/1.1 416", 0) == 0);
    // Before: {"error": "HTTP 416"}, and no Content-Type.
    CHECK(answer.find("\r\nContent-Type: application/json\r\n") != std::string::npos);
    CHECK(answer.find(R"("error": "Range header ')" + range + "' not understood: the service serves one range of bytes") !=
          std::string::npos);
  }
}

TEST_CASE("http api: an exception escaping a route is answered 500 as JSON, its text logged and not sent") {
  JobService jobs(fresh_dir("route-exception"));
  StatusBoard board;
  // A worker name in Latin-1, which only a test can give (a broker reads
  // names from JSON): /api/workers' JSON cannot carry it, and the JSON
  // library throws from the status route, which `guarded` does not wrap.
  FarmProgress progress;
  progress.worker_views.emplace_back();
  progress.worker_views.back().name = "sc\xe8ne";
  board.update(progress);
  std::mutex log_mutex;
  std::vector<std::string> lines;
  HttpApi api(jobs, any_port(), &board, [&](const std::string& line) {
    std::lock_guard<std::mutex> lock(log_mutex);
    lines.push_back(line);
  });
  const std::string answer = exchange_until_closed(
      port_of(api), "GET /api/workers HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n", 2000);
  CHECK(answer.rfind("HTTP/1.1 500", 0) == 0);
  // Before: "EXCEPTION_WHAT: [json.exception.type_error.316] ..." and {"error": "HTTP 500"}.
  CHECK(answer.find("EXCEPTION_WHAT") == std::string::npos);
  CHECK(answer.find("json.exception") == std::string::npos);
  CHECK(answer.find("\r\nContent-Type: application/json\r\n") != std::string::npos);
  CHECK(answer.find(R"x("error": "internal error of the service (its log tells more)")x") != std::string::npos);
  std::lock_guard<std::mutex> lock(log_mutex);
  REQUIRE(lines.size() == 1);
  CHECK(lines[0].rfind("GET /api/workers: answered 500: [json.exception.type_error.316]", 0) == 0);
}

TEST_CASE("http api: a percent-encoded Content-Length or Transfer-Encoding is refused 400, not decoded") {
  JobService jobs(fresh_dir("encoded-framing"));
  HttpApi api(jobs, any_port());
  const std::string head = "POST /api/jobs HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\n";
  // Before, httplib read "%32" as 2 and "%63hunked" as chunked: the body ended
  // where a proxy in front, seeing neither, would not end it.
  for (const std::string& request :
       {head + "Content-Length: %32\r\n\r\n{}", head + "Transfer-Encoding: %63hunked\r\n\r\n2\r\n{}\r\n0\r\n\r\n",
        head + "content-length: 1%30\r\n\r\n{}"}) {
    CAPTURE(request);
    const std::string answer = exchange_until_closed(port_of(api), request, 2000);
    CHECK(answer.rfind("HTTP/1.1 400", 0) == 0);
    CHECK(answer.find(R"("error": "Content-Length or Transfer-Encoding percent-encoded)") != std::string::npos);
    CHECK(answer.find("\r\nConnection: close\r\n") != std::string::npos);
  }
  // A '%' elsewhere in the head is no matter.
  const std::string other = exchange_until_closed(
      port_of(api), "GET /api/jobs HTTP/1.1\r\nHost: x\r\nX-Note: 100%\r\nConnection: close\r\n\r\n", 2000);
  CHECK(other.rfind("HTTP/1.1 200", 0) == 0);
}

TEST_CASE("http api: a header line folded onto the one before is refused 400 and its connection closed, not dropped") {
  JobService jobs(fresh_dir("folded"));
  HttpApi api(jobs, any_port());
  for (const std::string fold : {" more", "\tmore", " X-B: 2"}) {
    CAPTURE(fold);
    // Before: the folded line was dropped (or read as a header of its own) and the request served 200.
    const std::string answer = exchange_until_closed(
        port_of(api), "GET /api/jobs HTTP/1.1\r\nHost: x\r\nX-A: 1\r\n" + fold + "\r\n\r\n", 2000);
    CHECK(answer.rfind("HTTP/1.1 400", 0) == 0);
    CHECK(answer.find("obsolete line folding") != std::string::npos);
    CHECK(answer.find("\r\nConnection: close\r\n") != std::string::npos);
  }
  // A space inside a header line is no fold.
  const std::string plain = exchange_until_closed(
      port_of(api), "GET /api/jobs HTTP/1.1\r\nHost: x\r\nX-A: 1 2\r\nConnection: close\r\n\r\n", 2000);
  CHECK(plain.rfind("HTTP/1.1 200", 0) == 0);
}

TEST_CASE("http api: a later HTTP/1.x is served as HTTP/1.1, another major version is refused 505, not 400") {
  JobService jobs(fresh_dir("versions"));
  HttpApi api(jobs, any_port());
  for (const std::string version : {"HTTP/1.2", "HTTP/1.9"}) {
    CAPTURE(version);
    // Before: 400 "malformed HTTP request".
    const std::string answer = exchange_until_closed(
        port_of(api), "GET /api/jobs " + version + "\r\nHost: x\r\nConnection: close\r\n\r\n", 2000);
    CHECK(answer.rfind("HTTP/1.1 200", 0) == 0);
  }
  for (const std::string version : {"HTTP/2.0", "HTTP/0.9", "HTTP/3.0"}) {
    CAPTURE(version);
    const std::string answer =
        exchange_until_closed(port_of(api), "GET /api/jobs " + version + "\r\nHost: x\r\n\r\n", 2000);
    CHECK(answer.rfind("HTTP/1.1 505", 0) == 0);
    CHECK(answer.find("HTTP version " + version + " not supported") != std::string::npos);
    CHECK(answer.find("\r\nConnection: close\r\n") != std::string::npos);
  }
  // No version of the form HTTP/D.D is still a malformed request.
  for (const std::string version : {"HTTP/1.10", "HTTP/11", "FTP/1.1"}) {
    CAPTURE(version);
    const std::string answer =
        exchange_until_closed(port_of(api), "GET /api/jobs " + version + "\r\nHost: x\r\n\r\n", 2000);
    CHECK(answer.rfind("HTTP/1.1 400", 0) == 0);
  }
}

TEST_CASE("http api: an HTTP/1.1 request without a Host, or with two, is refused 400, the client's requests name it") {
  JobService jobs(fresh_dir("host"));
  HttpApi api(jobs, any_port());
  // Before: served 200.
  const std::string missing = exchange_until_closed(port_of(api), "GET /api/jobs HTTP/1.1\r\n\r\n", 2000);
  CHECK(missing.rfind("HTTP/1.1 400", 0) == 0);
  CHECK(missing.find("Host: missing") != std::string::npos);
  CHECK(missing.find("\r\nConnection: close\r\n") != std::string::npos);
  const std::string twice = exchange_until_closed(
      port_of(api), "GET /api/jobs HTTP/1.1\r\nHost: a\r\nHost: b\r\n\r\n", 2000);
  CHECK(twice.rfind("HTTP/1.1 400", 0) == 0);
  CHECK(twice.find("Host: given 2 times") != std::string::npos);
  // HTTP/1.0 has no Host to require.
  CHECK(exchange_until_closed(port_of(api), "GET /api/jobs HTTP/1.0\r\n\r\n", 2000).rfind("HTTP/1.1 200", 0) == 0);
  // What rayfarm submit, status, fetch and cancel send names its host.
  ApiClient client(api.address());
  const uint64_t id = client.submit(tiny_submission(1));
  CHECK(client.status(id).at("id") == id);
  CHECK_THROWS_WITH_AS(client.frame(id, 1), doctest::Contains("not rendered yet"), ApiError);
  CHECK(client.cancel(id).at("state") == "cancelled");
}

TEST_CASE("http api: an empty Host is a Host (RFC 9112 3.2), served alone, not refused as missing, and beside another it is two") {
  JobService jobs(fresh_dir("empty-host"));
  HttpApi api(jobs, any_port());
  // Before: 400 "Host: missing".
  for (const std::string host : {"Host:", "Host: ", "host: \t "}) {
    CAPTURE(host);
    const std::string answer = exchange_until_closed(
        port_of(api), "GET /api/jobs HTTP/1.1\r\n" + host + "\r\nConnection: close\r\n\r\n", 2000);
    CHECK(answer.rfind("HTTP/1.1 200", 0) == 0);
  }
  // Before: "Host: a" alone was seen, and served.
  for (const std::string hosts : {"Host: a\r\nHost:\r\n", "Host:\r\nHost: \r\n"}) {
    CAPTURE(hosts);
    const std::string answer = exchange_until_closed(port_of(api), "GET /api/jobs HTTP/1.1\r\n" + hosts + "\r\n", 2000);
    CHECK(answer.rfind("HTTP/1.1 400", 0) == 0);
    CHECK(answer.find("Host: given 2 times") != std::string::npos);
  }
  // Counted for its own request only: the next one on the connection has none.
  const std::string both = exchange_until_closed(
      port_of(api), "GET /api/jobs HTTP/1.1\r\nHost:\r\n\r\nGET /api/jobs HTTP/1.1\r\n\r\n", 2000);
  CHECK(both.rfind("HTTP/1.1 200", 0) == 0);
  CHECK(count_of(both, "HTTP/1.1 400") == 1);
  CHECK(both.find("Host: missing") != std::string::npos);
}

TEST_CASE("http api: a target in absolute-form is routed by its path (RFC 9112 3.2.2), not answered 404") {
  JobService jobs(fresh_dir("absolute-form"));
  HttpApi api(jobs, any_port());
  const uint64_t id = jobs.submit(submission_json(tiny_submission(1)));
  const std::string authority = "127.0.0.1:" + std::to_string(port_of(api));
  const auto answer_to = [&](const std::string& request_line, const std::string& more = "") {
    return exchange_until_closed(port_of(api), request_line + "\r\nHost: " + authority + "\r\n" + more +
                                                   "Connection: close\r\n\r\n", 2000);
  };
  // Before: 404 "no such resource".
  const std::string list = answer_to("GET http://" + authority + "/api/jobs HTTP/1.1");
  CHECK(list.rfind("HTTP/1.1 200", 0) == 0);
  CHECK(list.find("\"id\": " + std::to_string(id)) != std::string::npos);
  // The scheme in any case; the authority, as Host, is not compared; a query is no part of the path.
  for (const std::string target : {"HTTP://elsewhere/api/jobs/1", "http://user@[::1]:9/api/jobs/%31?x=/y"}) {
    CAPTURE(target);
    const std::string status = answer_to("GET " + target + " HTTP/1.1");
    CHECK(status.rfind("HTTP/1.1 200", 0) == 0);
    CHECK(status.find("\"state\": \"queued\"") != std::string::npos);
  }
  const std::string cancel =
      answer_to("POST http://" + authority + "/api/jobs/1/cancel HTTP/1.1", "Content-Length: 0\r\n");
  CHECK(cancel.rfind("HTTP/1.1 200", 0) == 0);
  CHECK(jobs.status(id)["state"] == "cancelled");
  // The path's methods, as for origin-form.
  const std::string put = answer_to("PUT http://" + authority + "/api/jobs HTTP/1.1");
  CHECK(put.rfind("HTTP/1.1 405", 0) == 0);
  CHECK(put.find("\r\nAllow: GET, HEAD, POST, OPTIONS\r\n") != std::string::npos);
  const std::string brew = answer_to("BREW http://" + authority + "/api/jobs/1/cancel HTTP/1.1");
  CHECK(brew.rfind("HTTP/1.1 501", 0) == 0);
  CHECK(brew.find("\r\nAllow: POST, OPTIONS\r\n") != std::string::npos);
  // An http URI without a host is refused (RFC 9110 4.2.1); another scheme names nothing here.
  for (const std::string target : {"http:///api/jobs", "http://:80/api/jobs", "http://u@/api/jobs"}) {
    CAPTURE(target);
    const std::string no_host = answer_to("GET " + target + " HTTP/1.1");
    CHECK(no_host.rfind("HTTP/1.1 400", 0) == 0);
    CHECK(no_host.find("an http URI names its host") != std::string::npos);
  }
  CHECK(answer_to("GET https://" + authority + "/api/jobs HTTP/1.1").rfind("HTTP/1.1 404", 0) == 0);
  // As in origin-form, an HTTP/1.1 request still names its Host.
  const std::string hostless =
      exchange_until_closed(port_of(api), "GET http://" + authority + "/api/jobs HTTP/1.1\r\n\r\n", 2000);
  CHECK(hostless.rfind("HTTP/1.1 400", 0) == 0);
}

TEST_CASE("http api: the broker's own 503 is named with its reason by the client, not as a proxy's") {
  JobService jobs(fresh_dir("client-busy"));
  HttpOptions options = any_port();
  options.max_connections = 2;  // 1 from one address
  HttpApi api(jobs, options, nullptr, [](const std::string&) {});
  const int held = connect_to(port_of(api));
  // Before, it read "the proxy at URL cannot reach the broker (HTTP 503)".
  CHECK_THROWS_WITH_AS(ApiClient(api.address()).list(),
                       doctest::Contains("is busy (HTTP 503): this address holds 1 connections to the service"),
                       BrokerUnreachable);
  ::close(held);
}
