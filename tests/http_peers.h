// What the HTTP API's tests share: a fresh state folder, a tiny submission,
// the API on any port, and raw sockets for requests httplib's client would
// not send (tests/http_api_test.cpp, tests/http_wire_test.cpp).
#pragma once

#include <doctest/doctest.h>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <filesystem>
#include <string>
#include <utility>

#include "service/http_api.h"
#include "service/submission.h"
#include "tests/service_scenes.h"
#include "tests/test_files.h"

namespace rayfarm::http_test {

inline std::string fresh_dir(const char* name) {
  const std::filesystem::path dir = test::process_dir("http-test") / name;
  std::filesystem::remove_all(dir);
  return dir.string();
}

inline Submission tiny_submission(int frames) {
  Submission s;
  for (int i = 0; i < frames; ++i) s.scenes.push_back({"f" + std::to_string(i) + ".nff", test::tiny_scene(i)});
  s.overrides.spp = 1;
  return s;
}

inline int port_of(const HttpApi& api) { return std::stoi(api.address().substr(api.address().rfind(':') + 1)); }

// `fd` connected to 127.0.0.1:port; returns it.
inline int connected_to_loopback(int fd, int port) {
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(static_cast<uint16_t>(port));
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  REQUIRE(::connect(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof addr) == 0);
  return fd;
}

// A socket listening on an ephemeral loopback port that nothing accepts on
// unless the test does: the kernel completes connections to it, as it does
// for a broker stopped or dying. Returns its descriptor; `url` its address.
inline int silent_listener(std::string& url) {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  socklen_t length = sizeof addr;
  REQUIRE(::bind(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof addr) == 0);
  REQUIRE(::listen(fd, 16) == 0);
  REQUIRE(::getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &length) == 0);
  url = "http://127.0.0.1:" + std::to_string(ntohs(addr.sin_port));
  return fd;
}

// A TCP connection to 127.0.0.1:port (its descriptor).
inline int connect_to(int port) { return connected_to_loopback(::socket(AF_INET, SOCK_STREAM, 0), port); }

// Reads what the service sends on `fd` until it closes the connection,
// nothing more comes within `wait_ms`, or, with `stop_at`, the answer holds
// it; then closes `fd`. `closed` (if given) says whether the service closed.
inline std::string read_answer(int fd, int wait_ms, const char* stop_at = nullptr, bool* closed = nullptr) {
  std::string answer;
  pollfd p{fd, POLLIN, 0};
  char buf[4096];
  bool ended = false;
  while (!ended && ::poll(&p, 1, wait_ms) == 1) {
    const ssize_t n = ::recv(fd, buf, sizeof buf, 0);
    ended = n <= 0;
    if (n > 0) answer.append(buf, static_cast<size_t>(n));
    if (stop_at && answer.find(stop_at) != std::string::npos) break;
  }
  ::close(fd);
  if (closed) *closed = ended;
  return answer;
}

// A fresh connection to 127.0.0.1:port with `request` sent on it as is: for
// requests httplib's client would not send.
inline int send_raw(int port, const std::string& request) {
  const int fd = connect_to(port);
  REQUIRE(::send(fd, request.data(), request.size(), 0) == static_cast<ssize_t>(request.size()));
  return fd;
}

// What the service answers `request` within `wait_ms` ("" if nothing), up
// to the end of its JSON reason.
inline std::string raw_exchange(int port, const std::string& request, int wait_ms) {
  return read_answer(send_raw(port, request), wait_ms, "}\n");
}

// Everything the service sends after `request` until it closes the
// connection, or "" if it has not closed it within `wait_ms`.
inline std::string exchange_until_closed(int port, const std::string& request, int wait_ms) {
  bool closed = false;
  const std::string answer = read_answer(send_raw(port, request), wait_ms, nullptr, &closed);
  return closed ? answer : "";
}

inline size_t count_of(const std::string& text, const std::string& part) {
  size_t n = 0;
  for (size_t at = text.find(part); at != std::string::npos; at = text.find(part, at + 1)) ++n;
  return n;
}

inline HttpOptions any_port(std::string token = "") {
  HttpOptions o;
  o.port = 0;
  o.token = std::move(token);
  return o;
}

// A TCP connection to 127.0.0.1:port from the loopback address `from` (e.g. "127.0.0.2").
inline int connect_from(const char* from, int port) {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in local{};
  local.sin_family = AF_INET;
  REQUIRE(::inet_pton(AF_INET, from, &local.sin_addr) == 1);
  REQUIRE(::bind(fd, reinterpret_cast<const sockaddr*>(&local), sizeof local) == 0);
  return connected_to_loopback(fd, port);
}

// Sends a GET of /api/jobs on `fd` and returns the answer ("" if none within 2 s).
inline std::string status_of_get(int fd) {
  const std::string request = "GET /api/jobs HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n";
  ::send(fd, request.data(), request.size(), MSG_NOSIGNAL);
  return read_answer(fd, 2000);
}

}  // namespace rayfarm::http_test
