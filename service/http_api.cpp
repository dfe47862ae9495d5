// The HTTP API; see http_api.h and docs/api.md.
#include "service/http_api.h"

#include <httplib.h>
#include <sys/socket.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cstdio>
#include <thread>

#include "protocol/codec.h"
#include "service/frame_file.h"
#include "service/http_connection.h"
#include "service/request_target.h"
#include "status/page_files.h"
#include "status/preview.h"
#include "status/route_table.h"
#include "status/status_routes.h"
#include "tracer/error.h"
#include "tracer/text_file.h"

namespace rayfarm {

using nlohmann::json;

namespace {

constexpr size_t kMaxBody = 512u << 20;  // a job of large scenes; the codec's scene limit is 256 MiB

// Threads for requests whose head has arrived (a connection waiting for one
// holds none, see http_connection.h): a few slow bodies or large frames at
// once still leave threads for the status page's polls. Idle threads cost
// little. 2 s of keep-alive still carries a page's polls (one a second) on
// one connection, and lets a tab that stopped polling go sooner.
constexpr size_t kHttpThreads = 64;
constexpr time_t kKeepAliveSeconds = 2;

// A 500 for a fault in the service's own code: what was thrown is the
// broker's log's business, not the client's (it names internals, and could
// quote a path of the head node).
constexpr const char* kInternalError = "internal error of the service (its log tells more)";

// Reasons quote what the client sent (a header's value, its JSON body as the
// parser read it), which need not be UTF-8: dump() threw on such a byte, from
// inside the handler's catch, and the client got "HTTP 500" and no reason.
// Such bytes are sent as U+FFFD.
void answer(httplib::Response& res, int status, const json& body) {
  res.status = status;
  res.set_content(body.dump(2, ' ', false, json::error_handler_t::replace) + "\n", "application/json");
}

void answer_error(httplib::Response& res, int status, const std::string& reason) {
  answer(res, status, json{{"error", reason}});
}

// A form body (curl -d's and --data-binary's default Content-Type) is parsed
// by httplib as form fields, and refused 413 past its small form limit
// however far below kMaxBody: a job of any real scene sent so.
bool is_form_body(const httplib::Request& req) {
  return req.get_header_value("Content-Type").rfind("application/x-www-form-urlencoded", 0) == 0;
}

// A request line httplib refused only for its method, one it does not know
// (FOO, or a WebDAV method): RFC 9110 9.1 answers that 501, not 400.
bool unknown_method(const httplib::Request& req) {
  static const std::string tchars = "!#$%&'*+-.^_`|~";
  if (req.method.empty() || (req.version != "HTTP/1.1" && req.version != "HTTP/1.0")) return false;
  for (char c : req.method)
    if (!std::isalnum(static_cast<unsigned char>(c)) && tchars.find(c) == std::string::npos) return false;
  for (const char* known : {"GET", "HEAD", "POST", "PUT", "DELETE", "CONNECT", "OPTIONS", "TRACE", "PATCH", "PRI"})
    if (req.method == known) return false;
  return true;
}

std::string bodies_over_budget() {
  return "the service is receiving other requests' bodies, as much as it holds at once: retry later";
}

// The path of the request's target, as routed: httplib leaves req.path empty
// for a request line it refused, and routes by its own reading of the target.
std::string path_of(const httplib::Request& req) { return routed_path(req.target).value_or(""); }

// The major version of a request line's "HTTP/D.D", or -1 for none such.
int major_version(const httplib::Request& req) {
  const std::string& v = req.version;
  if (v.size() != 8 || v.rfind("HTTP/", 0) != 0 || !std::isdigit(static_cast<unsigned char>(v[5])) || v[6] != '.' ||
      !std::isdigit(static_cast<unsigned char>(v[7])))
    return -1;
  return v[5] - '0';
}

// httplib answers 400 a head it could not read, whatever the cause; the
// connection's stream knows when the cause has a status of its own.
int status_of_refusal(const httplib::Request& req, int status) {
  if (status != 400) return status;
  switch (HttpServer::request_fault()) {
    case RequestFault::line_too_long:
    case RequestFault::head_too_long: return 431;
    case RequestFault::head_too_slow:
    case RequestFault::body_too_slow: return 408;
    case RequestFault::body_too_long: return 413;
    case RequestFault::over_budget: return 503;
    case RequestFault::encoded_framing:
    case RequestFault::folded_line:
    case RequestFault::empty_idempotency_key:
    case RequestFault::none:
      // RFC 9110 15.6.6: a major version not served is told apart from a malformed request.
      if (major_version(req) >= 0 && major_version(req) != 1) return 505;
      return unknown_method(req) ? 501 : 400;
  }
  return 400;
}

// Refusals httplib makes itself, before any handler: no route, a body over
// the limit, a request it cannot read.
std::string reason_of_refusal(const httplib::Request& req, int status) {
  switch (status) {
    case 404: return "no such resource (see docs/api.md)";
    case 413:
      if (is_form_body(req))
        return "a body sent as a form (Content-Type: application/x-www-form-urlencoded, curl -d's default) is "
               "limited to " + std::to_string(CPPHTTPLIB_FORM_URL_ENCODED_PAYLOAD_MAX_LENGTH) +
               " bytes: send the job as JSON (curl -H 'Content-Type: application/json' --data-binary @job.json)";
      return "request body larger than " + std::to_string(kMaxBody >> 20) + " MiB";
    case 414:
      return "request path (with its query) longer than " + std::to_string(CPPHTTPLIB_REQUEST_URI_MAX_LENGTH) +
             " bytes";
    case 400:
      if (HttpServer::request_fault() == RequestFault::encoded_framing)
        return "Content-Length or Transfer-Encoding percent-encoded: their values are sent as they are meant";
      if (HttpServer::request_fault() == RequestFault::empty_idempotency_key)
        return "Idempotency-Key: " + idempotency_key_fault("");
      if (HttpServer::request_fault() == RequestFault::folded_line)
        return "a header line begins with white space (obsolete line folding, RFC 9112 5.2): send each header "
               "on one line";
      return "malformed HTTP request";
    case 408:
      if (HttpServer::request_fault() == RequestFault::body_too_slow)
        return "request body arriving slower than " + std::to_string(kMinBodyBytesPerSecond >> 10) + " KiB/s";
      return "request head not received whole within " + std::to_string(kRequestHeadSeconds) + " s";
    case 431:
      if (HttpServer::request_fault() == RequestFault::head_too_long)
        return "request head (request line and headers) longer than " + std::to_string(kMaxRequestHeadBytes) + " bytes";
      return "request header line longer than " + std::to_string(CPPHTTPLIB_HEADER_MAX_LENGTH) + " bytes";
    case 503: return bodies_over_budget();
    case 505: return "HTTP version " + req.version + " not supported: the service speaks HTTP/1.1 (and 1.0)";
    case 501: return "method " + req.method + " not implemented (docs/api.md lists the methods of each path)";
    // httplib refuses a Range header it cannot parse before any handler runs.
    case 416:
      return "Range header '" + req.get_header_value("Range") +
             "' not understood: the service serves one range of bytes (Range: bytes=FIRST-LAST, FIRST- or -LAST), "
             "or send none";
    case 500: return kInternalError;
    default: return "HTTP " + std::to_string(status);
  }
}

// httplib refuses a body over its limit only once it has read it to the last
// announced byte: a client announcing 10^12 bytes and sending them held a
// thread reading for as long as it went on, and one sending none was told
// after the read timeout. Refused by the announced length instead, at once;
// a length that is no number, or two that differ, is no request to read.
bool refused_by_length(const httplib::Request& req, httplib::Response& res) {
  const size_t lengths = req.get_header_value_count("Content-Length");
  if (lengths == 0) return false;
  const std::string length = req.get_header_value("Content-Length");
  for (size_t i = 1; i < lengths; ++i) {
    if (req.get_header_value("Content-Length", i) != length) {
      answer_error(res, 400, "Content-Length: given twice, as " + length + " and " +
                                 req.get_header_value("Content-Length", i));
      return true;
    }
  }
  if (length.empty() || length.size() > 19 || length.find_first_not_of("0123456789") != std::string::npos) {
    answer_error(res, 400, "Content-Length: expected a number of bytes, found '" + length + "'");
    return true;
  }
  const size_t limit = is_form_body(req) ? CPPHTTPLIB_FORM_URL_ENCODED_PAYLOAD_MAX_LENGTH : kMaxBody;
  if (std::stoull(length) <= limit) return false;
  answer_error(res, 413, reason_of_refusal(req, 413));
  return true;
}

// httplib reads a body as chunked or by its Content-Length; with any other
// transfer coding (gzip, "gzip, chunked", two headers) it read until the
// client closed, then refused it 400 after the read timeout. Refused at once
// as RFC 9112 6.1 asks, 501, and the connection closed: where this request
// ends cannot be told.
bool refused_transfer_coding(const httplib::Request& req, httplib::Response& res) {
  const size_t headers = req.get_header_value_count("Transfer-Encoding");
  if (headers == 0) return false;
  std::string codings = req.get_header_value("Transfer-Encoding");
  for (size_t i = 1; i < headers; ++i) codings += ", " + req.get_header_value("Transfer-Encoding", i);
  std::string lower = codings;
  for (char& c : lower) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (lower == "chunked") return false;
  answer_error(res, 501, "Transfer-Encoding: only chunked is supported, found '" + codings + "'");
  return true;
}

// httplib keeps a header's name as sent up to its colon, white space
// included: "Transfer-Encoding : chunked" was no Transfer-Encoding to it,
// and its body was read by the Content-Length beside it, while a proxy in
// front that trims the name reads it chunked: a request smuggled past the
// proxy. RFC 9112 5.1 asks such a request be refused 400.
bool refused_header_name(const httplib::Request& req, httplib::Response& res) {
  static const std::string tchars = "!#$%&'*+-.^_`|~";
  for (const auto& [name, value] : req.headers) {
    const bool token = !name.empty() && std::all_of(name.begin(), name.end(), [](char c) {
      return std::isalnum(static_cast<unsigned char>(c)) || tchars.find(c) != std::string::npos;
    });
    if (token) continue;
    answer_error(res, 400, "header '" + name + "': a header name is a token, without white space before its colon");
    return true;
  }
  return false;
}

// httplib serves a request without a Host header, or with several; RFC 9112
// 3.2 has an HTTP/1.1 request name its host once, and a server refuse any
// other 400 (a proxy in front may route by one Host, the service read another).
// An empty Host is one: its value is valid (a uri-host may be empty), and 3.3
// has the server name itself in its place.
bool refused_host(const httplib::Request& req, httplib::Response& res) {
  const size_t hosts = req.get_header_value_count("Host") + HttpServer::empty_host_lines();
  if (hosts > 1) {
    answer_error(res, 400, "Host: given " + std::to_string(hosts) + " times, expected once");
    return true;
  }
  if (hosts == 1 || req.version != "HTTP/1.1") return false;
  answer_error(res, 400, "Host: missing, an HTTP/1.1 request names the host it is sent to (RFC 9112 3.2)");
  return true;
}

// httplib routes by the target as written; the routes match the path it
// names (service/request_target.h), set here before any route is chosen.
// An http target without a host is no URI to serve (RFC 9110 4.2.1).
// httplib's request is its own, const only in a handler's view.
bool refused_target(const httplib::Request& req, httplib::Response& res) {
  const std::optional<std::string> path = routed_path(req.target);
  if (!path) {
    answer_error(res, 400, "request target '" + req.target + "': an http URI names its host");
    return true;
  }
  const_cast<httplib::Request&>(req).path = *path;
  return false;
}

// httplib reads a chunked body and ignores a Content-Length beside it, and
// served what followed the chunks as the connection's next request: behind a
// proxy that goes by the length, a request smuggled past it. RFC 9112 6.3
// lets such a request be refused, and asks that its connection be closed.
bool refused_two_lengths(const httplib::Request& req, httplib::Response& res) {
  if (!req.has_header("Transfer-Encoding") || !req.has_header("Content-Length")) return false;
  answer_error(res, 400, "Transfer-Encoding and Content-Length given together: which ends the body is ambiguous");
  return true;
}

// httplib reads a body only for the methods that usually carry one (POST,
// PUT, PATCH, DELETE): a GET's body was left unread, and its bytes were
// parsed as the connection's next request. Such a request is answered and
// its connection closed, the body read away meanwhile.
bool body_left_unread(const httplib::Request& req) {
  for (const char* reads : {"POST", "PUT", "PATCH", "DELETE", "PRI"})
    if (req.method == reads) return false;
  return req.has_header("Transfer-Encoding") ||
         (req.has_header("Content-Length") && req.get_header_value("Content-Length") != "0");
}

// A body announced by its length takes its share of the budget of bodies
// being received before any of it is read; without one it takes it as it
// arrives (http_connection.h). Many bodies at once, each within the
// payload limit, took memory without bound.
bool refused_by_budget(const httplib::Request& req, httplib::Response& res) {
  if (!req.has_header("Content-Length") || body_left_unread(req)) return false;
  if (HttpServer::reserve_body(std::stoull(req.get_header_value("Content-Length")))) return false;
  answer_error(res, 503, bodies_over_budget());
  res.set_header("Retry-After", "2");
  return true;
}

// httplib serves the ranges a request's Range header asks of any answer: of
// a 404's or a POST's JSON (a client got `{\n  "e` with its 404 status), and
// as many as the header names, each up to the whole body (2,000 ranges of a
// 13 KiB page file were a 26 MB answer, of a frame they would be gigabytes).
// RFC 9110 14.2 defines Range for GET only and lets a server ignore it: the
// service serves one range of a GET's successful answer, else the whole.
// httplib's request is its own, const only in a handler's view.
void ignore_range(const httplib::Request& req) { const_cast<httplib::Request&>(req).ranges.clear(); }

void ignore_ranges_not_served(const httplib::Request& req) {
  if (req.method != "GET" || req.ranges.size() > 1) ignore_range(req);
}

// httplib answers a range past the end 416 with the range asked for, as if
// served ("bytes 999999-13068/13069"), and the Content-Type of a body it no
// longer sends. RFC 9110 14.4 has a 416 name only the length: "bytes */13069".
void answer_unsatisfiable_range(httplib::Response& res) {
  const std::string range = res.get_header_value("Content-Range");
  const size_t slash = range.rfind('/');
  res.headers.erase("Content-Range");
  res.headers.erase("Content-Type");
  if (slash != std::string::npos) res.set_header("Content-Range", "bytes */" + range.substr(slash + 1));
}

// The token of an `Authorization: Bearer TOKEN` header, "" for any other.
// The scheme is case-insensitive (RFC 9110 11.1: "bearer" and "BEARER" are
// "Bearer"), and one or more spaces may follow it; the token is compared as is.
std::string bearer_token_of(const std::string& authorization) {
  static const std::string scheme = "bearer";
  if (authorization.size() <= scheme.size() || authorization[scheme.size()] != ' ') return "";
  for (size_t i = 0; i < scheme.size(); ++i)
    if (std::tolower(static_cast<unsigned char>(authorization[i])) != scheme[i]) return "";
  const size_t token = authorization.find_first_not_of(' ', scheme.size());
  return token == std::string::npos ? "" : authorization.substr(token);
}

// The request's Idempotency-Key, "" if it has none; InputError naming the
// header for one a client could not mean (two, empty, too long, not ASCII).
std::string idempotency_key_of(const httplib::Request& req) {
  const size_t keys = req.get_header_value_count("Idempotency-Key");
  if (keys == 0) return "";
  if (keys > 1) throw InputError("Idempotency-Key: given " + std::to_string(keys) + " times, expected once");
  const std::string key = req.get_header_value("Idempotency-Key");
  const std::string fault = idempotency_key_fault(key);
  if (!fault.empty()) throw InputError("Idempotency-Key: " + fault);
  return key;
}

// A body sent again is the same bytes: its hash, not its parse, is compared.
SubmissionKey submission_key_of(const httplib::Request& req) {
  const std::string key = idempotency_key_of(req);
  if (key.empty()) return {};
  return {key, protocol::hash_hex(protocol::fnv1a64(req.body))};
}

uint64_t id_of(const httplib::Request& req) { return std::stoull(req.matches[1].str()); }

// Frames are numbered from 1 in the API, as in the output names OUT-0001.png.
uint32_t frame_of(const httplib::Request& req) {
  const unsigned long n = std::stoul(req.matches[2].str());
  if (n < 1 || n > kMaxFramesPerJob) throw NotFound("frames are numbered 1.." + std::to_string(kMaxFramesPerJob));
  return static_cast<uint32_t>(n - 1);
}

// Every handler runs inside this: whatever it throws becomes a JSON reason and
// a status code; nothing a client sends can take the service down.
template <class Fn> httplib::Server::Handler guarded(Fn fn) {
  return [fn](const httplib::Request& req, httplib::Response& res) {
    try {
      fn(req, res);
    } catch (const NotFound& e) {
      answer_error(res, 404, e.what());
    } catch (const NotReady& e) {
      answer_error(res, 409, e.what());
    } catch (const KeyReused& e) {
      answer_error(res, 422, e.what());
    } catch (const InputError& e) {
      answer_error(res, 400, e.what());
    } catch (const json::exception& e) {
      answer_error(res, 400, "invalid JSON: " + short_json_error(e.what()));
    } catch (const std::out_of_range& e) {
      answer_error(res, 404, "number out of range");
    } catch (const std::exception& e) {
      answer_error(res, 500, e.what());
    }
  };
}

}  // namespace

HttpOptions parse_http_address(const std::string& text) {
  HttpOptions o;
  const size_t colon = text.rfind(':');
  if (colon == std::string::npos || colon == 0) throw InputError("--http: expected HOST:PORT, found '" + text + "'");
  o.host = text.substr(0, colon);
  if (o.host.size() > 2 && o.host.front() == '[' && o.host.back() == ']') o.host = o.host.substr(1, o.host.size() - 2);
  const std::string port = text.substr(colon + 1);
  if (port.empty() || port.size() > 5 || port.find_first_not_of("0123456789") != std::string::npos ||
      std::stoi(port) > 65535)
    throw InputError("--http: port must be 0..65535, found '" + port + "'");
  o.port = std::stoi(port);
  return o;
}

std::string idempotency_key_fault(const std::string& key) {
  const std::string expected = "expected 1 to " + std::to_string(kMaxIdempotencyKey) + " printable ASCII characters";
  if (key.empty()) return expected + ", found none";
  if (key.size() > kMaxIdempotencyKey) return expected + ", found " + std::to_string(key.size());
  // Said by its code, not quoted: a control character would reach logs and terminals.
  const auto odd = std::find_if(key.begin(), key.end(), [](char c) { return c < 0x20 || c > 0x7e; });
  if (odd == key.end()) return "";
  char what[32];
  std::snprintf(what, sizeof what, "byte 0x%02x", static_cast<unsigned>(static_cast<unsigned char>(*odd)));
  return expected + ", found " + what + " at character " + std::to_string(odd - key.begin() + 1);
}

bool is_loopback(const std::string& host) {
  return host == "localhost" || host == "::1" || host.rfind("127.", 0) == 0;
}

std::string read_token_file(const std::string& path) {
  std::string token = read_text_file(path);
  const auto first = token.find_first_not_of(" \t\r\n");
  const auto last = token.find_last_not_of(" \t\r\n");
  if (first == std::string::npos) throw InputError(path + ": the token file is empty");
  token = token.substr(first, last - first + 1);
  // A second line (a comment, a token appended) or a control character was
  // kept inside the token: no Authorization header can carry it, so the
  // broker started and answered 401 to every client given the same file.
  // Said without the token's text: it is a secret.
  const auto control = std::find_if(token.begin(), token.end(), [](char c) {
    return static_cast<unsigned char>(c) < 0x20 || c == 0x7f;
  });
  if (control != token.end()) {
    char what[48];
    std::snprintf(what, sizeof what, *control == '\n' || *control == '\r' ? "a line break" : "control character 0x%02x",
                  static_cast<unsigned>(static_cast<unsigned char>(*control)));
    throw InputError(path + ": expected the token on one line of printable characters, found " + what + " after " +
                     std::to_string(control - token.begin()) + " characters (no HTTP header can carry it)");
  }
  return token;
}

struct HttpApi::Impl {
  JobService& jobs;
  HttpOptions options;
  const StatusBoard* status;
  HttpServer server{kHttpThreads};
  RouteTable routes{server};
  int port = 0;
  socket_t listen_socket = -1;  // as set_socket_options saw it, before httplib's bind and listen
  std::thread thread;

  LogSink log;

  Impl(JobService& j, const HttpOptions& o, const StatusBoard* s, LogSink l)
      : jobs(j), options(o), status(s), log(std::move(l)) {
    if (!is_loopback(o.host) && o.token.empty())
      throw InputError("--http " + o.host + ": an API bound beyond loopback needs a bearer token (--token-file)");
    if (o.max_connections < 2)
      throw InputError("--http-connections: expected at least 2 (one address may hold half), found " +
                       std::to_string(o.max_connections));
    server.set_connection_limits(o.max_connections, o.max_connections / 2, log);
    server.set_payload_max_length(kMaxBody);
    server.set_body_budget(o.body_budget);
    server.set_keep_alive_timeout(kKeepAliveSeconds);
    // httplib's default sets SO_REUSEPORT, which lets a second broker bind the
    // same port and take half the requests; SO_REUSEADDR alone still lets a
    // restarted broker bind past its old connections in TIME_WAIT.
    server.set_socket_options([this](socket_t sock) {
      listen_socket = sock;
      const int yes = 1;
      ::setsockopt(sock, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof yes);
    });
    server.set_pre_routing_handler([this](const httplib::Request& req, httplib::Response& res) {
      return screen(req, res);
    });
    // httplib answered every `Expect: 100-continue` with 100 Continue, and a
    // request refused anyway (a wrong token, a body over the limit) had its
    // client start sending the body it was about to refuse. It is screened
    // first, and only one that passes is told to go on.
    server.set_expect_100_continue_handler([this](const httplib::Request& req, httplib::Response& res) {
      return screen(req, res) == httplib::Server::HandlerResponse::Handled ? res.status : 100;
    });
    mount_routes();
    port = o.port == 0 ? server.bind_to_any_port(o.host) : (server.bind_to_port(o.host, o.port) ? o.port : -1);
    if (port <= 0)
      throw InputError("--http: cannot bind " + o.host + ":" + std::to_string(o.port) + " (in use, or no such address)");
    // httplib listens with a backlog of 5: a burst of new connections, the
    // accept thread a moment late, and the kernel drops the rest for a 1 s retry.
    ::listen(listen_socket, SOMAXCONN);
    thread = std::thread([this] { server.listen_after_bind(); });
  }

  ~Impl() {
    // httplib's stop() does nothing until its listen loop has begun: an API
    // dropped at once (the broker after it refusing its allow folder or
    // worker port) left the loop to begin after it, accepting forever, and
    // `broker --serve` hung at start without a word.
    while (thread.joinable() && !server.is_running()) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    server.stop();
    if (thread.joinable()) thread.join();
  }

  // What is told before a request's body is read: refusals of the request
  // as it stands, whatever it sends.
  httplib::Server::HandlerResponse screen(const httplib::Request& req, httplib::Response& res) {
    ignore_ranges_not_served(req);
    if (refused_target(req, res) || refused_header_name(req, res) || refused_host(req, res) ||
        refused_two_lengths(req, res) || refused_transfer_coding(req, res))
      return httplib::Server::HandlerResponse::Handled;
    if (body_left_unread(req) && !res.has_header("Connection")) {  // screened twice after an Expect
      res.set_header("Connection", "close");
      HttpServer::close_after_response();
    }
    // The page holds no data; it asks for the token itself (docs/status-page.md).
    // HEAD is GET without the body (a monitor's `curl -I`).
    const bool page_file = (req.method == "GET" || req.method == "HEAD") && find_page_file(req.path);
    if (!options.token.empty() && bearer_token_of(req.get_header_value("Authorization")) != options.token &&
        !page_file) {
      answer_error(res, 401, "missing or wrong bearer token");
      return httplib::Server::HandlerResponse::Handled;
    }
    // Before a body is read: a wrong method is told at once, whatever it sends.
    if (routes.answer_other_method(req, res)) return httplib::Server::HandlerResponse::Handled;
    // httplib reads a POST without a length until the client closes, which
    // `curl -X POST URL` never does: its cancel would wait out the read
    // timeout and fail. Answered at once instead.
    if (req.method == "POST" && !req.has_header("Content-Length") && !req.has_header("Transfer-Encoding")) {
      answer_error(res, 411, "a POST needs a Content-Length header (an empty body: curl -d '')");
      return httplib::Server::HandlerResponse::Handled;
    }
    if (refused_by_length(req, res) || refused_by_budget(req, res)) return httplib::Server::HandlerResponse::Handled;
    return httplib::Server::HandlerResponse::Unhandled;
  }

  // Every state, zeros included, for the jobs gauge of /metrics.
  std::map<std::string, int> jobs_by_state() const {
    std::map<std::string, int> out;
    for (JobState st : {JobState::queued, JobState::running, JobState::done, JobState::failed, JobState::cancelled})
      out[job_state_name(st)] = 0;
    for (const json& j : jobs.list()) out[j.at("state").get<std::string>()] += 1;
    return out;
  }

  // A finished job's last frame from the state folder, for the page when the
  // status board no longer holds its image.
  std::optional<std::string> final_png(uint64_t id) const {
    try {
      const json s = jobs.status(id);
      const int frames = s.at("frames_done").get<int>();
      if (frames < 1) return std::nullopt;
      const RgbImage img = decode_frame(jobs.frame(id, static_cast<uint32_t>(frames - 1)), "job " + std::to_string(id));
      return preview_png(img.width, img.height, img.rgb, std::vector<bool>(static_cast<size_t>(img.height), true));
    } catch (const std::exception&) {
      return std::nullopt;
    }
  }

  void mount_routes() {
    const std::string job = std::string("/api/jobs/") + kPathNumber;
    routes.post("/api/jobs", guarded([this](const httplib::Request& req, httplib::Response& res) {
      const SubmissionKey key = submission_key_of(req);  // refused before the body is parsed
      // The parser of configs and protocol messages: a key given twice is refused, not last-one-wins.
      const Submitted job = jobs.submit(parse_json_text(req.body, "request body"), key);
      // The first answer again, lost on its way: a retry learns the job is the one it sent.
      json status = jobs.status(job.id);
      if (job.earlier) status["earlier_submission"] = true;
      answer(res, 201, status);
    }));
    routes.get("/api/jobs", guarded([this](const httplib::Request&, httplib::Response& res) {
      answer(res, 200, jobs.list());
    }));
    routes.get(job, guarded([this](const httplib::Request& req, httplib::Response& res) {
      answer(res, 200, jobs.status(id_of(req)));
    }));
    routes.post(job + "/cancel", guarded([this](const httplib::Request& req, httplib::Response& res) {
      answer(res, 200, jobs.cancel(id_of(req)));
    }));
    routes.get(job + "/frames/" + kPathNumber, guarded([this](const httplib::Request& req, httplib::Response& res) {
      res.set_content(jobs.frame(id_of(req), frame_of(req)), "application/octet-stream");
    }));
    routes.get(job + "/records/" + kPathNumber, guarded([this](const httplib::Request& req, httplib::Response& res) {
      answer(res, 200, jobs.record(id_of(req), frame_of(req)));
    }));
    if (status) {
      mount_status_page(routes);
      mount_status_api(routes, *status, StatusSources{[this] { return jobs_by_state(); },
                                                      [this](uint64_t id) { return final_png(id); }});
    }
    // A handler's exception that `guarded` does not catch (the status page's
    // routes run without it): httplib answered 500 with the exception's text
    // in an EXCEPTION_WHAT header and "HTTP 500" as the reason. The text is
    // logged here instead, and the client told only that the fault is the service's.
    server.set_exception_handler([this](const httplib::Request& req, httplib::Response& res, std::exception_ptr e) {
      std::string what = "an exception of no standard type";
      try {
        std::rethrow_exception(e);
      } catch (const std::exception& x) {
        what = x.what();
      } catch (...) {
      }
      write_log(log, req.method + " " + req.path + ": answered 500: " + what);
      answer_error(res, 500, kInternalError);
    });
    server.set_error_handler([this](const httplib::Request& req, httplib::Response& res) {
      // httplib 0.11 hands only std::exception to the exception handler: for
      // any other it still sets this header ("UNKNOWN"), never to be sent.
      if (res.has_header("EXCEPTION_WHAT")) {
        write_log(log, req.method + " " + req.path + ": answered 500: " + res.get_header_value("EXCEPTION_WHAT"));
        res.headers.erase("EXCEPTION_WHAT");
      }
      if (res.body.empty()) {
        res.status = status_of_refusal(req, res.status);
        answer_error(res, res.status, reason_of_refusal(req, res.status));
        // As a 405 does (RFC 9110 15.6.2): the methods that would have served.
        if (res.status == 501 && unknown_method(req)) res.set_header("Allow", routes.allowed_methods(path_of(req)));
      }
      // What follows a refused request on its connection may be the rest of
      // it (a body not read, a head not read whole), not a next request.
      if (res.status == 503) res.set_header("Retry-After", "2");
      ignore_range(req);  // an error is answered whole
      res.set_header("Connection", "close");
      HttpServer::close_after_response();
    });
    // httplib adds its Keep-Alive header to every answer it does not close
    // itself, after the error handler ran: a refusal went out saying both
    // `Connection: close` and `Keep-Alive: timeout=2, max=5`. And it adds
    // its own `Connection: close` for a client that asked to close, beside
    // the error handler's: the header went out twice.
    server.set_post_routing_handler([](const httplib::Request&, httplib::Response& res) {
      // httplib cuts an answer to its range whatever its status, and one a
      // handler set to 200 (the JSON answers) went out as 200 with a part.
      if (res.status == 200 && res.has_header("Content-Range")) res.status = 206;
      // A range past the end (its body cut away), not a refused Range header (a JSON reason).
      if (res.status == 416 && res.body.empty()) answer_unsatisfiable_range(res);
      if (res.get_header_value("Connection") != "close") return;
      res.headers.erase("Keep-Alive");
      res.headers.erase("Connection");
      res.set_header("Connection", "close");
    });
  }
};

HttpApi::HttpApi(JobService& jobs, const HttpOptions& options, const StatusBoard* status, LogSink log)
    : impl_(std::make_unique<Impl>(jobs, options, status, std::move(log))) {}
HttpApi::~HttpApi() = default;

std::string HttpApi::address() const {
  const std::string& h = impl_->options.host;
  return "http://" + (h.find(':') != std::string::npos ? "[" + h + "]" : h) + ":" + std::to_string(impl_->port);
}

}  // namespace rayfarm
