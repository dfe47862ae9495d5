// One stream per connection; see http_connection.h.
#include "service/http_connection.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstring>

namespace rayfarm {
namespace {

using Clock = std::chrono::steady_clock;

// How long a closing connection still reads what its client sends: closing
// with unread bytes resets the connection, and the client may lose the
// answer it was sent (a 405 to a PUT whose body was never read).
constexpr auto kLingerOnClose = std::chrono::milliseconds(500);

// Rounded up: a wait rounded down ended before the deadline, and a head that
// was too slow was then refused 400 as malformed instead of 408.
int ms_until(Clock::time_point deadline) {
  const auto left = std::chrono::ceil<std::chrono::milliseconds>(deadline - Clock::now()).count();
  return static_cast<int>(std::clamp<long long>(left, 0, 1 << 30));
}

bool wait_for(socket_t sock, short events, Clock::time_point deadline) {
  pollfd p{sock, events, 0};
  for (;;) {
    const int n = ::poll(&p, 1, ms_until(deadline));
    if (n >= 0 || errno != EINTR) return n > 0;
  }
}

void ip_and_port(const sockaddr_storage& addr, std::string& ip, int& port) {
  char text[INET6_ADDRSTRLEN] = "";
  if (addr.ss_family == AF_INET) {
    const auto& a = reinterpret_cast<const sockaddr_in&>(addr);
    ::inet_ntop(AF_INET, &a.sin_addr, text, sizeof text);
    port = ntohs(a.sin_port);
  } else if (addr.ss_family == AF_INET6) {
    const auto& a = reinterpret_cast<const sockaddr_in6&>(addr);
    ::inet_ntop(AF_INET6, &a.sin6_addr, text, sizeof text);
    port = ntohs(a.sin6_port);
  }
  ip = text;
}

// A connection's bytes, buffered across its requests, with the head of the
// current request watched: its deadline and its lines' lengths.
class ConnectionStream : public httplib::Stream {
 public:
  ConnectionStream(socket_t sock, std::chrono::seconds read_timeout, std::chrono::seconds write_timeout,
                   size_t body_limit)
      : sock_(sock), read_timeout_(read_timeout), write_timeout_(write_timeout), body_limit_(body_limit) {}

  // True when a next request has begun to arrive within `idle`.
  bool wait_for_request(std::chrono::seconds idle) const {
    return begin_ < end_ || wait_for(sock_, POLLIN, Clock::now() + idle);
  }

  void start_request() {
    deadline_ = Clock::now() + std::chrono::seconds(kRequestHeadSeconds);
    in_head_ = true;
    body_bytes_ = 0;
    cut_ = false;
    line_ = 0;
    line_bytes_ = 0;
    fault_ = HeadFault::none;
    close_ = false;
  }

  HeadFault fault() const { return fault_; }
  void close_after_response() { close_ = true; }
  bool closing() const { return close_; }

  // Sends nothing more, and reads what the client still sends for a moment
  // so that closing does not reset the connection under the last answer.
  void linger() {
    ::shutdown(sock_, SHUT_WR);
    const auto until = Clock::now() + kLingerOnClose;
    char scrap[4096];
    while (wait_for(sock_, POLLIN, until) && ::recv(sock_, scrap, sizeof scrap, 0) > 0) {
    }
  }

  bool is_readable() const override {
    return begin_ < end_ || wait_for(sock_, POLLIN, read_deadline());
  }

  bool is_writable() const override { return wait_for(sock_, POLLOUT, Clock::now() + write_timeout_); }

  // Past a head line's limit, or the body's, it reads as the end of the
  // input: httplib then refuses the request without waiting for, or
  // keeping, the rest.
  ssize_t read(char* ptr, size_t size) override {
    if (cut_) return 0;
    if (begin_ == end_ && !fill()) return -1;
    size_t n = std::min(size, end_ - begin_);
    if (in_head_) {
      n = watch_head(n);
    } else if (body_bytes_ + n > body_limit_) {
      fault_ = HeadFault::body_too_long;
      cut_ = true;
      return 0;
    } else {
      body_bytes_ += n;
    }
    std::memcpy(ptr, buffer_ + begin_, n);
    begin_ += n;
    return static_cast<ssize_t>(n);
  }

  ssize_t write(const char* ptr, size_t size) override {
    if (!is_writable()) return -1;
    for (;;) {
      const ssize_t n = ::send(sock_, ptr, size, MSG_NOSIGNAL);
      if (n >= 0 || errno != EINTR) return n;
    }
  }

  void get_remote_ip_and_port(std::string& ip, int& port) const override {
    sockaddr_storage addr{};
    socklen_t length = sizeof addr;
    if (::getpeername(sock_, reinterpret_cast<sockaddr*>(&addr), &length) == 0) ip_and_port(addr, ip, port);
  }

  void get_local_ip_and_port(std::string& ip, int& port) const override {
    sockaddr_storage addr{};
    socklen_t length = sizeof addr;
    if (::getsockname(sock_, reinterpret_cast<sockaddr*>(&addr), &length) == 0) ip_and_port(addr, ip, port);
  }

  socket_t socket() const override { return sock_; }

 private:
  // The request's deadline, or httplib's read timeout for each read if sooner.
  Clock::time_point read_deadline() const {
    return std::min(request_deadline(), Clock::now() + read_timeout_);
  }

  // The body's (up to the service's 512 MiB) grows with what has arrived of it.
  Clock::time_point request_deadline() const {
    if (in_head_) return deadline_;
    return deadline_ + std::chrono::duration_cast<Clock::duration>(
                           std::chrono::duration<double>(double(body_bytes_) / kMinBodyBytesPerSecond));
  }

  bool fill() {
    if (!wait_for(sock_, POLLIN, read_deadline())) {
      if (Clock::now() >= request_deadline()) fault_ = in_head_ ? HeadFault::too_slow : HeadFault::body_too_slow;
      return false;
    }
    for (;;) {
      const ssize_t n = ::recv(sock_, buffer_, sizeof buffer_, 0);
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) return false;
      begin_ = 0;
      end_ = static_cast<size_t>(n);
      return true;
    }
  }

  // How many of the next `n` buffered bytes to hand out: up to the head's end,
  // or up to the byte that takes a line past its limit (then cut).
  size_t watch_head(size_t n) {
    for (size_t i = 0; i < n; ++i) {
      const char c = buffer_[begin_ + i];
      ++line_bytes_;
      const size_t limit = line_ == 0 ? CPPHTTPLIB_REQUEST_URI_MAX_LENGTH : CPPHTTPLIB_HEADER_MAX_LENGTH;
      if (line_bytes_ > limit) {
        if (line_ > 0) fault_ = HeadFault::line_too_long;
        cut_ = true;
        return i + 1;
      }
      if (c != '\n') continue;
      if (line_ > 0 && line_bytes_ <= 2) {  // the blank line: the head is whole
        in_head_ = false;
        deadline_ = Clock::now() + std::chrono::seconds(kRequestHeadSeconds);
        return i + 1;
      }
      ++line_;
      line_bytes_ = 0;
    }
    return n;
  }

  socket_t sock_;
  std::chrono::seconds read_timeout_, write_timeout_;
  size_t body_limit_;  // bytes, a chunked body's framing included
  char buffer_[4096];
  size_t begin_ = 0, end_ = 0;
  Clock::time_point deadline_;  // the head's, then the body's before any of it arrived
  bool in_head_ = false;
  size_t body_bytes_ = 0;  // of the current request, read so far
  bool cut_ = false;
  size_t line_ = 0;        // of the head, the request line 0
  size_t line_bytes_ = 0;  // so far, its line ending included
  HeadFault fault_ = HeadFault::none;
  bool close_ = false;
};

thread_local ConnectionStream* current = nullptr;

}  // namespace

HeadFault HttpServer::head_fault() { return current ? current->fault() : HeadFault::none; }

void HttpServer::close_after_response() {
  if (current) current->close_after_response();
}

bool HttpServer::process_and_close_socket(socket_t sock) {
  ConnectionStream stream(sock, std::chrono::seconds(read_timeout_sec_), std::chrono::seconds(write_timeout_sec_),
                          payload_max_length_);
  current = &stream;
  bool ok = true;
  for (size_t served = 0; ok && svr_sock_ != INVALID_SOCKET && served < keep_alive_max_count_; ++served) {
    if (!stream.wait_for_request(std::chrono::seconds(keep_alive_timeout_sec_))) break;
    stream.start_request();
    bool client_closes = false;
    ok = process_request(stream, served + 1 == keep_alive_max_count_, client_closes, nullptr);
    if (client_closes || stream.closing()) break;
  }
  current = nullptr;
  // Only an error answer leaves the client sending: a client that is done
  // closes its end, and an idle one has sent nothing since its last answer.
  if (stream.closing()) stream.linger();
  ::close(sock);
  return ok;
}

}  // namespace rayfarm
