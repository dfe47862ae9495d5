// One stream per connection; see http_connection.h.
#include "service/http_connection.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/eventfd.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <limits>
#include <map>
#include <mutex>
#include <optional>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

namespace rayfarm {
namespace {

using Clock = std::chrono::steady_clock;

// How long a closing connection still reads what its client sends: closing
// with unread bytes resets the connection, and the client may lose the
// answer it was sent (a 405 to a PUT whose body was never read).
constexpr auto kLingerOnClose = std::chrono::milliseconds(500);

// What a connection buffers while its head arrives with no thread reading it;
// a longer head is read on by a server thread. Browsers' heads, cookies and
// all, fit.
constexpr size_t kHeadBufferBytes = 16 << 10;

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

}  // namespace

// Taken in steps by bodies as they arrive (or at once, for a length told
// ahead), given back once their answer is sent.
class BodyBudget {
 public:
  explicit BodyBudget(size_t bytes) : limit_(bytes) {}

  bool take(size_t bytes) {
    size_t used = used_.load();
    do {
      if (bytes > limit_ - used) return false;
    } while (!used_.compare_exchange_weak(used, used + bytes));
    return true;
  }
  void give_back(size_t bytes) { used_ -= bytes; }
  size_t limit() const { return limit_; }

 private:
  const size_t limit_;
  std::atomic<size_t> used_{0};
};

namespace {

// A body arriving takes the budget in steps of this much, not per read.
constexpr size_t kBodyBudgetStep = 64 << 10;

// A connection's bytes, buffered across its requests, with the head of the
// current request watched: its deadline and its lines' lengths.
class ConnectionStream : public httplib::Stream {
 public:
  ConnectionStream(socket_t sock, std::chrono::seconds read_timeout, std::chrono::seconds write_timeout,
                   size_t body_limit, std::shared_ptr<BodyBudget> budget)
      : sock_(sock),
        read_timeout_(read_timeout),
        write_timeout_(write_timeout),
        body_limit_(body_limit),
        budget_(std::move(budget)),
        buffer_(kHeadBufferBytes) {}
  ~ConnectionStream() override { release_body(); }
  ConnectionStream(const ConnectionStream&) = delete;
  ConnectionStream& operator=(const ConnectionStream&) = delete;

  // Sets aside `bytes` more of the body budget for the current request.
  bool reserve_body(size_t bytes) {
    if (!budget_->take(bytes)) return false;
    reserved_ += bytes;
    return true;
  }
  // Sees that `bytes` in all are set aside for the current request.
  bool reserve_body_of(size_t bytes) { return bytes <= reserved_ || reserve_body(bytes - reserved_); }
  // Once its answer is sent: what the request's body held is free again.
  void release_body() {
    budget_->give_back(reserved_);
    reserved_ = 0;
  }

  // True when a next request has begun to arrive within `idle`.
  bool wait_for_request(std::chrono::seconds idle) const {
    return begin_ < end_ || wait_for(sock_, POLLIN, Clock::now() + idle);
  }

  bool has_bytes() const { return begin_ < end_; }

  // True when what is buffered holds a whole request head, or as much of
  // one as the buffer takes: a server thread can read it without waiting.
  bool head_buffered() const {
    if (end_ - begin_ >= buffer_.size()) return true;
    const auto first = buffer_.begin() + static_cast<std::ptrdiff_t>(begin_);
    const auto last = buffer_.begin() + static_cast<std::ptrdiff_t>(end_);
    for (auto at = std::find(first, last, '\n'); at != last; at = std::find(at + 1, last, '\n')) {
      if (at + 1 != last && at[1] == '\n') return true;
      if (at + 2 < last && at[1] == '\r' && at[2] == '\n') return true;
    }
    return false;
  }

  // Reads what has arrived without waiting: 0 at the client's end of input,
  // -1 on an error, more when it may go on (nothing having arrived yet too).
  ssize_t pull() {
    if (begin_ > 0) {
      std::memmove(buffer_.data(), buffer_.data() + begin_, end_ - begin_);
      end_ -= begin_;
      begin_ = 0;
    }
    if (end_ == buffer_.size()) return 1;  // full: the head's reader takes it from here
    for (;;) {
      const ssize_t n = ::recv(sock_, buffer_.data() + end_, buffer_.size() - end_, MSG_DONTWAIT);
      if (n < 0 && errno == EINTR) continue;
      if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) return 1;
      if (n > 0) end_ += static_cast<size_t>(n);
      note_head_begun();
      return n;
    }
  }

  // The head's deadline runs from its first byte, whoever read it.
  void note_head_begun() {
    if (head_begun_ || begin_ == end_) return;
    head_begun_ = true;
    head_deadline_ = Clock::now() + std::chrono::seconds(kRequestHeadSeconds);
  }
  bool head_begun() const { return head_begun_; }
  Clock::time_point head_deadline() const { return head_deadline_; }

  void start_request() {
    note_head_begun();
    deadline_ = head_begun_ ? head_deadline_ : Clock::now() + std::chrono::seconds(kRequestHeadSeconds);
    head_begun_ = false;
    version_seen_ = false;
    in_head_ = true;
    body_bytes_ = 0;
    cut_ = false;
    line_ = 0;
    line_bytes_ = 0;
    head_bytes_ = 0;
    line_start_.clear();
    line_percent_ = false;
    fault_ = RequestFault::none;
    empty_hosts_ = 0;
    close_ = false;
  }

  RequestFault fault() const { return fault_; }
  size_t empty_hosts() const { return empty_hosts_; }
  void close_after_response() { close_ = true; }
  bool closing() const { return close_; }

  // Sends nothing more, and reads what the client still sends for a moment
  // so that closing does not reset the connection under the last answer.
  void linger() {
    ::shutdown(sock_, SHUT_WR);
    const auto until = Clock::now() + kLingerOnClose;
    while (wait_for(sock_, POLLIN, until) && discard() > 0) {
    }
  }

  // Reads and drops what has arrived: 0 at the end of input, -1 on an
  // error, more when it may go on.
  ssize_t discard() {
    begin_ = end_ = 0;
    for (;;) {
      const ssize_t n = ::recv(sock_, buffer_.data(), buffer_.size(), MSG_DONTWAIT);
      if (n >= 0 || errno != EINTR) return n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK) ? 1 : n;
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
      if (line_ == 0 && !version_seen_) serve_minor_version_as_1_1();
      n = watch_head(n);
    } else if (body_bytes_ + n > body_limit_) {
      fault_ = RequestFault::body_too_long;
      cut_ = true;
      return 0;
    } else if (body_bytes_ + n > reserved_ && !reserve_body(std::max(kBodyBudgetStep, body_bytes_ + n - reserved_))) {
      fault_ = RequestFault::over_budget;
      cut_ = true;
      return 0;
    } else {
      body_bytes_ += n;
    }
    std::memcpy(ptr, buffer_.data() + begin_, n);
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
      if (Clock::now() >= request_deadline()) fault_ = in_head_ ? RequestFault::head_too_slow : RequestFault::body_too_slow;
      return false;
    }
    for (;;) {
      const ssize_t n = ::recv(sock_, buffer_.data(), buffer_.size(), 0);
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) return false;
      begin_ = 0;
      end_ = static_cast<size_t>(n);
      return true;
    }
  }

  // httplib decodes percent-encoding in every header's value: it read
  // "Content-Length: %32" as 2 and "Transfer-Encoding: %63hunked" as
  // chunked, where a proxy in front sees no valid length or coding, and the
  // two end the body in different places.
  void note_header_byte(char c) {
    if (line_ == 0) return;
    if (line_start_.size() < kFramingNameBytes)
      line_start_ += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    if (c == '%') line_percent_ = true;
  }
  bool encoded_framing() const {
    return line_percent_ &&
           (line_start_.rfind("content-length:", 0) == 0 || line_start_.rfind("transfer-encoding:", 0) == 0);
  }
  // httplib drops a header line without a value: an "Idempotency-Key:" left
  // empty (a script's unset variable) made a submission without a key, and
  // its retry a second job; an empty "Host:", which RFC 9112 3.2 allows, was
  // refused as missing. Told only for a line held whole.
  bool empty_value_of(const std::string& name) const {
    return line_start_.size() < kFramingNameBytes && line_start_.rfind(name, 0) == 0 &&
           line_start_.find_first_not_of(" \t\r", name.size()) == std::string::npos;
  }
  bool empty_idempotency_key() const { return empty_value_of("idempotency-key:"); }

  // httplib refuses 400 any version but HTTP/1.0 and HTTP/1.1, where RFC
  // 9110 2.5 has a server take a later 1.x as the highest 1.x it knows: the
  // request line's "HTTP/1.2" is read as "HTTP/1.1" once it is buffered
  // whole, before httplib reads its version. (A major version other than 1
  // is answered 505 by the API.)
  void serve_minor_version_as_1_1() {
    const auto first = buffer_.begin() + static_cast<std::ptrdiff_t>(begin_);
    const auto last = buffer_.begin() + static_cast<std::ptrdiff_t>(end_);
    const auto newline = std::find(first, last, '\n');
    if (newline == last) return;  // not whole yet
    version_seen_ = true;
    static const std::string later = " HTTP/1.?\r";
    if (newline - first < static_cast<std::ptrdiff_t>(later.size())) return;  // partly read already
    char* version = &*(newline - static_cast<std::ptrdiff_t>(later.size()));
    if (std::memcmp(version, later.data(), 8) != 0 || version[9] != '\r') return;
    if (version[8] >= '2' && version[8] <= '9') version[8] = '1';
  }

  // How many of the next `n` buffered bytes to hand out: up to the head's end,
  // or up to the byte that takes a line past its limit (then cut).
  size_t watch_head(size_t n) {
    for (size_t i = 0; i < n; ++i) {
      const char c = buffer_[begin_ + i];
      ++line_bytes_;
      if (++head_bytes_ > kMaxRequestHeadBytes) {
        fault_ = RequestFault::head_too_long;
        cut_ = true;
        return i + 1;
      }
      const size_t limit = line_ == 0 ? CPPHTTPLIB_REQUEST_URI_MAX_LENGTH : CPPHTTPLIB_HEADER_MAX_LENGTH;
      if (line_bytes_ > limit) {
        if (line_ > 0) fault_ = RequestFault::line_too_long;
        cut_ = true;
        return i + 1;
      }
      // httplib drops such a line (no colon) or reads it as a header of its
      // own; RFC 9112 5.2 has a server refuse it or join it to the line before.
      if (line_ > 0 && line_bytes_ == 1 && (c == ' ' || c == '\t')) {
        fault_ = RequestFault::folded_line;
        cut_ = true;
        return i + 1;
      }
      if (c != '\n') {
        note_header_byte(c);
        continue;
      }
      if (encoded_framing() || empty_idempotency_key()) {
        fault_ = encoded_framing() ? RequestFault::encoded_framing : RequestFault::empty_idempotency_key;
        cut_ = true;
        return i + 1;
      }
      if (empty_value_of("host:")) ++empty_hosts_;
      line_start_.clear();
      line_percent_ = false;
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
  std::shared_ptr<BodyBudget> budget_;
  size_t reserved_ = 0;  // of the budget, by the current request
  std::vector<char> buffer_;
  size_t begin_ = 0, end_ = 0;
  bool head_begun_ = false;  // the next request's first byte has arrived
  Clock::time_point head_deadline_;
  Clock::time_point deadline_;  // the head's, then the body's before any of it arrived
  bool in_head_ = false;
  bool version_seen_ = false;  // the request line's end has been buffered (and its version read)
  size_t body_bytes_ = 0;  // of the current request, read so far
  bool cut_ = false;
  size_t line_ = 0;        // of the head, the request line 0
  size_t line_bytes_ = 0;  // so far, its line ending included
  size_t head_bytes_ = 0;  // so far, all its lines
  static constexpr size_t kFramingNameBytes = 24;  // "transfer-encoding:", an "idempotency-key:" line left empty
  std::string line_start_;                          // of the current header line, lower case
  bool line_percent_ = false;                       // a '%' in it
  RequestFault fault_ = RequestFault::none;
  size_t empty_hosts_ = 0;  // "Host:" lines without a value, of the current request
  bool close_ = false;
};

thread_local ConnectionStream* current = nullptr;

std::string peer_address(socket_t sock) {
  sockaddr_storage addr{};
  socklen_t length = sizeof addr;
  std::string ip;
  int port = 0;
  if (::getpeername(sock, reinterpret_cast<sockaddr*>(&addr), &length) == 0) ip_and_port(addr, ip, port);
  return ip;
}

// How often refusals for the connection limits are logged while they go on.
constexpr auto kRefusalLogInterval = std::chrono::minutes(1);

}  // namespace

// The connections open, in all and by client address. Taken on httplib's
// accept thread, given back by whichever thread closes a connection.
class HttpServer::Admission {
 public:
  Admission(size_t total, size_t per_client, LogSink log)
      : total_(total), per_client_(per_client), log_(std::move(log)) {}

  // "" when `address` may open one more connection (it is then counted),
  // otherwise why not, for its client.
  std::string admit(const std::string& address) {
    std::string why, line;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      size_t& mine = by_address_[address];
      if (open_ < total_ && mine < per_client_) {
        ++open_;
        ++mine;
        return "";
      }
      if (mine == 0) by_address_.erase(address);
      if (open_ >= total_) {
        why = "the service has " + std::to_string(open_) + " connections open, the most it takes: retry later";
        line = std::to_string(open_) + " connections open, the most the HTTP API takes (--http-connections)";
      } else {
        why = "this address holds " + std::to_string(mine) +
              " connections to the service, the most one address may: close some, or retry later";
        line = std::to_string(mine) + " connections open from " + address +
               ", the most one address may hold (half of --http-connections)";
      }
      line = due_log_line(line);
    }
    if (!line.empty()) write_log(log_, line);
    return why;
  }

  void release(const std::string& address) {
    std::lock_guard<std::mutex> lock(mutex_);
    --open_;
    const auto it = by_address_.find(address);
    if (it != by_address_.end() && --it->second == 0) by_address_.erase(it);
  }

 private:
  // A refusal is logged when none was in the last minute; the others are
  // counted into the next line (a flood of them is one line a minute).
  std::string due_log_line(const std::string& what) {
    ++refused_;
    const auto now = Clock::now();
    if (last_log_ && now - *last_log_ < kRefusalLogInterval) return "";
    std::string line = "HTTP API: " + what + ": new connections are answered 503 and closed";
    if (refused_ > 1) line += " (" + std::to_string(refused_ - 1) + " refused since the last such line)";
    last_log_ = now;
    refused_ = 0;
    return line;
  }

  std::mutex mutex_;
  const size_t total_, per_client_;
  size_t open_ = 0;
  std::map<std::string, size_t> by_address_;
  LogSink log_;
  size_t refused_ = 0;  // refusals not logged yet, this one included
  std::optional<Clock::time_point> last_log_;
};

// Closes its socket, and gives its place back, when it is done with.
struct HttpServer::Connection {
  Connection(std::shared_ptr<Admission> a, std::string from) : admission(std::move(a)), address(std::move(from)) {}
  // The place first: a client that sees its connection end can open another.
  ~Connection() {
    if (admission) admission->release(address);
    if (stream) ::close(stream->socket());
  }
  Connection(const Connection&) = delete;
  Connection& operator=(const Connection&) = delete;

  std::shared_ptr<Admission> admission;  // null: not counted
  std::string address;                   // the client's
  std::unique_ptr<ConnectionStream> stream;
  size_t served = 0;           // requests answered on it
  Clock::time_point idle_end;  // when it closes if no request begins
  bool lingering = false;      // closing: only its client's last bytes are read
  bool handed_over = false;    // by the watcher: serve what is buffered, head whole or not

  // When the watcher stops waiting for it.
  Clock::time_point deadline() const {
    if (!lingering && stream->head_begun()) return stream->head_deadline();
    return idle_end;
  }
};

// The server's threads, and one more that watches every connection waiting
// for a request's head (or lingering before its close) and hands it to a
// server thread once the head is whole, its deadline passed or its client
// closed. httplib's accept loop hands each new connection here: it is
// admitted or refused at once, on that loop's thread, and an admitted one
// then served by a server thread.
class HttpServer::Waiting : public httplib::TaskQueue {
 public:
  Waiting(HttpServer& server, size_t threads) : server_(server), pool_(threads) {
    wake_ = ::eventfd(0, EFD_CLOEXEC | EFD_NONBLOCK);
    if (wake_ >= 0) watcher_ = std::thread([this] { watch(); });  // without, each thread waits on its own
  }

  ~Waiting() override {
    if (wake_ >= 0) ::close(wake_);
  }

  void enqueue(std::function<void()> fn) override { fn(); }

  // For a server thread as soon as one is free.
  void serve_later(std::unique_ptr<Connection> c) {
    Connection* raw = c.release();  // a task is copied: it cannot own the connection
    HttpServer& server = server_;
    pool_.enqueue([&server, raw] { server.serve(std::unique_ptr<Connection>(raw)); });
  }

  // Connections still waiting are closed; requests being served finish.
  void shutdown() override {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stopping_ = true;
    }
    wake();
    if (watcher_.joinable()) watcher_.join();
    server_.waiting_ = nullptr;
    pool_.shutdown();
  }

  bool park(std::unique_ptr<Connection>& connection) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (stopping_ || wake_ < 0) return false;
      incoming_.push_back(std::move(connection));
    }
    wake();
    return true;
  }

 private:
  void wake() {
    const uint64_t one = 1;
    if (wake_ < 0) return;
    [[maybe_unused]] const auto n = ::write(wake_, &one, sizeof one);
  }

  void watch() {
    std::vector<std::unique_ptr<Connection>> watched;
    std::vector<pollfd> polled;
    for (;;) {
      {
        std::lock_guard<std::mutex> lock(mutex_);
        if (stopping_) break;
        for (auto& c : incoming_) watched.push_back(std::move(c));
        incoming_.clear();
      }
      auto next = Clock::now() + std::chrono::hours(1);
      polled.assign(1, pollfd{wake_, POLLIN, 0});
      for (const auto& c : watched) {
        polled.push_back(pollfd{c->stream->socket(), POLLIN, 0});
        next = std::min(next, c->deadline());
      }
      if (::poll(polled.data(), polled.size(), ms_until(next)) < 0 && errno != EINTR) break;
      uint64_t count;
      [[maybe_unused]] const auto n = ::read(wake_, &count, sizeof count);
      const auto now = Clock::now();
      // Back to front: a connection done with is swapped out for the last.
      for (size_t i = watched.size(); i-- > 0;) {
        if (!settle(watched[i], polled[i + 1].revents != 0, now)) continue;
        if (watched[i]) hand_over(std::move(watched[i]));
        watched[i] = std::move(watched.back());
        watched.pop_back();
      }
    }
    watched.clear();  // each closes as it goes
    std::lock_guard<std::mutex> lock(mutex_);
    incoming_.clear();
  }

  // True when the watcher is done with `c`: closed (then reset) or to be
  // handed to a server thread.
  static bool settle(std::unique_ptr<Connection>& c, bool readable, Clock::time_point now) {
    ConnectionStream& stream = *c->stream;
    ssize_t got = 1;
    if (readable) got = c->lingering ? stream.discard() : stream.pull();
    const bool ended = got <= 0;
    if (c->lingering || !stream.has_bytes()) {
      if (!ended && now < c->deadline()) return false;
      c.reset();  // a client gone, or idle past the keep-alive time: closed
      return true;
    }
    // A head cut short, or past its deadline, is the server thread's to refuse.
    return ended || stream.head_buffered() || now >= c->deadline();
  }

  void hand_over(std::unique_ptr<Connection> c) {
    c->handed_over = true;
    serve_later(std::move(c));
  }

  HttpServer& server_;
  httplib::ThreadPool pool_;
  int wake_ = -1;  // an eventfd: a connection parked, or stopping
  std::mutex mutex_;
  std::vector<std::unique_ptr<Connection>> incoming_;
  bool stopping_ = false;
  std::thread watcher_;
};

HttpServer::HttpServer(size_t threads)
    : admission_(std::make_shared<Admission>(kDefaultMaxConnections, kDefaultMaxConnections / 2, LogSink{})),
      body_budget_(std::make_shared<BodyBudget>(std::numeric_limits<size_t>::max())) {
  new_task_queue = [this, threads] {
    auto* queue = new Waiting(*this, threads);
    waiting_ = queue;
    return queue;
  };
}

void HttpServer::set_connection_limits(size_t total, size_t per_client, LogSink log) {
  admission_ = std::make_shared<Admission>(total, per_client, std::move(log));
}

void HttpServer::set_body_budget(size_t bytes) { body_budget_ = std::make_shared<BodyBudget>(bytes); }

size_t HttpServer::body_budget() const { return body_budget_->limit(); }

bool HttpServer::reserve_body(size_t bytes) { return current && current->reserve_body_of(bytes); }

RequestFault HttpServer::request_fault() { return current ? current->fault() : RequestFault::none; }

size_t HttpServer::empty_host_lines() { return current ? current->empty_hosts() : 0; }

void HttpServer::close_after_response() {
  if (current) current->close_after_response();
}

bool HttpServer::park(std::unique_ptr<Connection>& connection) {
  Waiting* waiting = waiting_;
  return waiting && waiting->park(connection);
}

bool HttpServer::process_and_close_socket(socket_t sock) {
  const std::string address = peer_address(sock);
  const std::string why = admission_->admit(address);
  if (!why.empty()) {
    refuse(sock, why);
    return true;
  }
  auto connection = std::make_unique<Connection>(admission_, address);
  connection->stream = std::make_unique<ConnectionStream>(sock, std::chrono::seconds(read_timeout_sec_),
                                                          std::chrono::seconds(write_timeout_sec_),
                                                          payload_max_length_, body_budget_);
  Waiting* waiting = waiting_;
  if (waiting)
    waiting->serve_later(std::move(connection));
  else
    serve(std::move(connection));
  return true;
}

// Without waiting for anything: the accept loop's thread runs it. What the
// client has sent so far is read away first, so that closing sends the
// answer and an end, not a reset that could overtake the answer.
void HttpServer::refuse(socket_t sock, const std::string& why) {
  const std::string body = nlohmann::json{{"error", why}}.dump(2) + "\n";
  const std::string answer = "HTTP/1.1 503 Service Unavailable\r\nConnection: close\r\nContent-Length: " +
                             std::to_string(body.size()) +
                             "\r\nContent-Type: application/json\r\nRetry-After: 2\r\n\r\n" + body;
  const auto read_away = [sock] {  // a little: a client sending on cannot hold the thread
    char drop[4096];
    for (int i = 0; i < 16 && ::recv(sock, drop, sizeof drop, MSG_DONTWAIT) > 0; ++i) {
    }
  };
  read_away();
  [[maybe_unused]] const auto sent = ::send(sock, answer.data(), answer.size(), MSG_DONTWAIT | MSG_NOSIGNAL);
  ::shutdown(sock, SHUT_WR);
  read_away();
  ::close(sock);
}

void HttpServer::serve(std::unique_ptr<Connection> connection) {
  ConnectionStream& stream = *connection->stream;
  bool ok = true;
  while (ok && svr_sock_ != INVALID_SOCKET && connection->served < keep_alive_max_count_) {
    if (!connection->handed_over && !stream.head_buffered()) {
      const ssize_t got = stream.pull();
      if (got <= 0 && !stream.has_bytes()) break;  // the client closed
      if (got > 0 && !stream.head_buffered()) {
        // The rest of the head is read by the watcher as it arrives, without this thread.
        connection->idle_end = Clock::now() + std::chrono::seconds(keep_alive_timeout_sec_);
        if (park(connection)) return;
        if (!stream.wait_for_request(std::chrono::seconds(keep_alive_timeout_sec_))) break;
      }
    }
    connection->handed_over = false;
    current = &stream;
    stream.start_request();
    bool client_closes = false;
    ok = process_request(stream, connection->served + 1 == keep_alive_max_count_, client_closes, nullptr);
    current = nullptr;
    stream.release_body();
    ++connection->served;
    if (client_closes || stream.closing()) break;
  }
  finish(std::move(connection));
}

// Only an error answer leaves the client sending: a client that is done
// closes its end, and an idle one has sent nothing since its last answer.
// The watcher reads its last bytes if it can, this thread if not.
void HttpServer::finish(std::unique_ptr<Connection> connection) {
  ConnectionStream& stream = *connection->stream;
  const socket_t sock = stream.socket();
  if (stream.closing() && !connection->lingering) {
    ::shutdown(sock, SHUT_WR);
    connection->lingering = true;
    connection->idle_end = Clock::now() + kLingerOnClose;
    if (park(connection)) return;
    stream.linger();
  }
}

}  // namespace rayfarm
