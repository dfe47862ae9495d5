// Admission: who may talk to the broker at all. The broker answers ZeroMQ's
// authentication requests (ZAP, RFC 27) on inproc://zeromq.zap.01 for both of
// its sockets. CURVE alone only proves a client knows the server's public key;
// this handler is what turns a key into an invitation:
//   keyed     -- only CURVE clients whose public key is in the allow folder;
//                the key (Z85) becomes the connection's "User-Id", so the
//                broker can bind each registration to it;
//   protected -- no keys: only loopback peers (the Redis "protected mode");
//   insecure  -- no keys, anyone (explicitly asked for with --insecure).
// Refusals are logged, at most once a minute per (address, key).
#pragma once

#include <chrono>
#include <functional>
#include <map>
#include <optional>
#include <string>

#include <zmq.hpp>

#include "protocol/curve_keys.h"

namespace rayfarm {

enum class AdmissionMode { keyed, protected_loopback, insecure };

struct AdmissionPolicy {
  AdmissionMode mode = AdmissionMode::protected_loopback;
  std::map<std::string, std::string> allowed;  // keyed: Z85 public key -> name
};

// The ZAP domain the broker's sockets set (NULL security asks ZAP only with one).
inline constexpr const char* kZapDomain = "rayfarm";

class ZapHandler {
 public:
  // Binds inproc://zeromq.zap.01 in `context`: create it before any socket
  // of that context binds, or early handshakes go unchecked.
  ZapHandler(zmq::context_t& context, AdmissionPolicy policy, std::function<void(const std::string&)> log);

  zmq::socket_t& socket() { return socket_; }  // poll it for ZMQ_POLLIN

  // Answers every request queued now; never blocks.
  void serve_pending();

  // Name of an admitted key ("" if unknown or not keyed).
  std::string name_of(const std::string& user_id) const;

  int refused() const { return refused_; }

 private:
  struct Verdict {
    bool admit;
    std::string user_id, reason;
  };
  Verdict judge(const std::string& mechanism, const std::string& address, const std::string& credentials) const;
  void log_refusal(const std::string& address, const std::string& who, const std::string& reason);

  zmq::socket_t socket_;
  AdmissionPolicy policy_;
  std::function<void(const std::string&)> log_;
  std::map<std::string, std::chrono::steady_clock::time_point> last_logged_;
  int refused_ = 0;
};

// The broker's own key and whom it admits, from --key FILE / --allow DIR /
// --insecure. Throws InputError for half a configuration or a bad key file.
struct BrokerKeys {
  std::optional<protocol::CurveKeyPair> own;  // set in keyed mode
  AdmissionPolicy policy;
};
BrokerKeys load_broker_keys(const std::string& key_file, const std::string& allow_dir, bool insecure);

// CURVE server (keyed) and the ZAP domain (keyed, protected); before bind.
void secure_broker_socket(zmq::socket_t& socket, const BrokerKeys& keys);

// The line the broker logs at start: who is admitted, loudly if anyone is unauthenticated.
std::string admission_banner(const BrokerKeys& keys, const std::string& endpoint);

// True for 127.0.0.0/8, ::1 and ::ffff:127.x.y.z.
bool is_loopback_address(const std::string& address);

}  // namespace rayfarm
