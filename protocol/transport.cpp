// ZeroMQ frame transport for RFP/3; see transport.h.
#include "protocol/transport.h"

#include <arpa/inet.h>
#include <netdb.h>
#include <sys/socket.h>

namespace rayfarm::protocol {

void configure_socket(zmq::socket_t& socket, uint64_t max_frame_bytes) {
  socket.set(zmq::sockopt::linger, 0);
  socket.set(zmq::sockopt::maxmsgsize, static_cast<int64_t>(max_frame_bytes));
}

std::optional<Frames> receive(zmq::socket_t& socket, std::string* identity, std::string* user_id) {
  Frames frames;
  bool first = true;
  if (user_id) user_id->clear();
  while (true) {
    zmq::message_t part;
    const auto got = socket.recv(part, first ? zmq::recv_flags::dontwait : zmq::recv_flags::none);
    if (!got) return std::nullopt;  // EAGAIN on the first part: nothing queued
    if (first && identity) {
      *identity = part.to_string();
    } else {
      if (user_id && frames.empty()) {
        // Metadata rides on the frames from the wire, not on ROUTER's identity frame.
        const char* uid = zmq_msg_gets(part.handle(), "User-Id");
        if (uid) *user_id = uid;
      }
      if (frames.size() < 16)
        frames.push_back(part.to_string());
      else
        frames.emplace_back();  // keep counting, do not keep bytes: decode() rejects it
    }
    first = false;
    if (!part.more()) break;
  }
  return frames;
}

bool send(zmq::socket_t& socket, const Frames& frames, const std::string* identity) {
  const size_t n = frames.size() + (identity ? 1 : 0);
  size_t i = 0;
  auto flags = [&] {
    return ++i < n ? zmq::send_flags::sndmore | zmq::send_flags::dontwait : zmq::send_flags::dontwait;
  };
  try {
    if (identity && !socket.send(zmq::buffer(*identity), flags())) return false;
    for (const auto& f : frames)
      if (!socket.send(zmq::buffer(f), flags())) return false;
  } catch (const zmq::error_t& e) {
    if (e.num() == EHOSTUNREACH) return false;  // ROUTER_MANDATORY: peer gone
    throw;
  }
  return true;
}

bool send(zmq::socket_t& socket, const Message& message, const std::string* identity) {
  return send(socket, encode(message), identity);
}

bool send_waiting(zmq::socket_t& socket, const Frames& frames) {
  for (size_t i = 0; i < frames.size(); ++i)
    if (!socket.send(zmq::buffer(frames[i]), i + 1 < frames.size() ? zmq::send_flags::sndmore : zmq::send_flags::none))
      return false;
  return true;
}

void poll_interruptible(zmq::pollitem_t* items, size_t count, int timeout_ms) {
  try {
    zmq::poll(items, count, std::chrono::milliseconds(timeout_ms));
  } catch (const zmq::error_t& e) {
    if (e.num() != EINTR) throw;
    for (size_t i = 0; i < count; ++i) items[i].revents = 0;
  }
}

std::string tcp_port_problem(const std::string& endpoint) {
  if (endpoint.rfind("tcp://", 0) != 0) return "";
  const auto colon = endpoint.rfind(':');
  if (colon < 6) return "";  // no port at all: ZeroMQ refuses that itself
  const std::string port = endpoint.substr(colon + 1);
  if (port == "*" || port == "0") return "";  // any port (a bind)
  const bool digits = !port.empty() && port.size() <= 5 && port.find_first_not_of("0123456789") == std::string::npos;
  if (!digits || std::stoi(port) < 1 || std::stoi(port) > 65535)
    return "the port '" + port + "' is no TCP port (expected 1..65535, or * for any when binding)";
  return "";
}

std::string farm_transport_problem(const std::string& endpoint) {
  if (endpoint.rfind("tcp://", 0) == 0) return "";
  if (endpoint.rfind("inproc://", 0) == 0)
    return "inproc:// reaches only sockets inside one process, never a broker's; expected tcp://HOST:PORT";
  return "a farm runs over TCP (a worker finds the announcements at its broker's host and the port the broker "
         "names, and a broker without keys admits loopback TCP peers only); expected tcp://HOST:PORT";
}

std::string broker_endpoint_problem(const std::string& endpoint) {
  if (const std::string problem = farm_transport_problem(endpoint); !problem.empty()) return problem;
  if (const std::string problem = tcp_port_problem(endpoint); !problem.empty()) return problem;
  const auto colon = endpoint.rfind(':');
  if (endpoint.rfind("tcp://", 0) != 0 || colon < 6) return "";
  const std::string port = endpoint.substr(colon + 1);
  if (port == "*" || port == "0")
    return "the port '" + port + "' means any free port to a bind, and no broker listens on it; give the port the "
           "broker's log names (\"workers connect to ... (announcements on ...)\")";
  return "";
}

std::string tcp_host_problem(const std::string& endpoint) {
  if (endpoint.rfind("tcp://", 0) != 0) return "";
  std::string host = endpoint.substr(6);
  if (const auto semicolon = host.find(';'); semicolon != std::string::npos) host = host.substr(semicolon + 1);  // SRC;HOST:PORT
  const auto colon = host.rfind(':');
  if (colon == std::string::npos) return "";  // no port: tcp_port_problem's and ZeroMQ's to report
  host = host.substr(0, colon);
  if (host.empty() || host == "*" || host.front() == '[') return "";  // [IPv6] is a literal
  unsigned char address[sizeof(in6_addr)];
  if (inet_pton(AF_INET, host.c_str(), address) == 1 || inet_pton(AF_INET6, host.c_str(), address) == 1) return "";
  addrinfo hints{};
  hints.ai_socktype = SOCK_STREAM;
  addrinfo* found = nullptr;
  const int rc = getaddrinfo(host.c_str(), nullptr, &hints, &found);
  if (found) freeaddrinfo(found);
  if (rc == 0) return "";
  return "the host name '" + host + "' cannot be resolved (" + gai_strerror(rc) + ")";
}

int endpoint_port(const std::string& endpoint) {
  const auto colon = endpoint.rfind(':');
  if (colon == std::string::npos) throw InputError("endpoint '" + endpoint + "' has no port");
  return std::stoi(endpoint.substr(colon + 1));
}

std::string endpoint_with_port(const std::string& endpoint, int port) {
  const auto colon = endpoint.rfind(':');
  if (colon == std::string::npos || colon < 6) throw InputError("endpoint '" + endpoint + "': expected tcp://HOST:PORT");
  return endpoint.substr(0, colon + 1) + std::to_string(port);
}

}  // namespace rayfarm::protocol
