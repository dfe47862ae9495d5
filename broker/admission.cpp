// The broker's ZAP handler; see admission.h.
#include "broker/admission.h"

#include <vector>

#include "protocol/transport.h"
#include "tracer/error.h"

namespace rayfarm {
namespace {

constexpr const char* kZapEndpoint = "inproc://zeromq.zap.01";

std::string z85(const std::string& binary_key) {
  if (binary_key.size() != 32) return "";
  char out[41];
  if (!zmq_z85_encode(out, reinterpret_cast<const uint8_t*>(binary_key.data()), 32)) return "";
  return out;
}

}  // namespace

bool is_loopback_address(const std::string& address) {
  return address.rfind("127.", 0) == 0 || address == "::1" || address.rfind("::ffff:127.", 0) == 0;
}

ZapHandler::ZapHandler(zmq::context_t& context, AdmissionPolicy policy, std::function<void(const std::string&)> log)
    : socket_(context, zmq::socket_type::rep), policy_(std::move(policy)), log_(std::move(log)) {
  socket_.set(zmq::sockopt::linger, 0);
  socket_.bind(kZapEndpoint);
}

ZapHandler::Verdict ZapHandler::judge(const std::string& mechanism, const std::string& address,
                                      const std::string& credentials) const {
  switch (policy_.mode) {
    case AdmissionMode::keyed: {
      if (mechanism != "CURVE") return {false, "", "no CURVE key (this farm admits invited keys only)"};
      const std::string key = z85(credentials);
      if (!policy_.allowed.count(key)) return {false, "", "key " + key + " is not invited"};
      return {true, key, ""};
    }
    case AdmissionMode::protected_loopback:
      if (!is_loopback_address(address))
        return {false, "", "unauthenticated farm admits loopback peers only (configure keys, or --insecure)"};
      return {true, "", ""};
    case AdmissionMode::insecure:
      return {true, "", ""};
  }
  return {false, "", "unknown admission mode"};
}

void ZapHandler::serve_pending() {
  for (int i = 0; i < 1000; ++i) {
    auto request = protocol::receive(socket_);
    if (!request) return;
    // RFC 27: version, request id, domain, address, routing id, mechanism, credentials...
    const protocol::Frames& f = *request;
    if (f.size() < 6 || f[0] != "1.0") {
      protocol::send(socket_, protocol::Frames{"1.0", f.size() > 1 ? f[1] : "", "500", "bad ZAP request", "", ""});
      continue;
    }
    const std::string& address = f[3];
    const std::string& mechanism = f[5];
    const std::string credentials = f.size() > 6 ? f[6] : "";
    const Verdict v = judge(mechanism, address, credentials);
    if (!v.admit) {
      ++refused_;
      log_refusal(address, mechanism == "CURVE" ? z85(credentials) : mechanism, v.reason);
    }
    protocol::send(socket_, protocol::Frames{"1.0", f[1], v.admit ? "200" : "400", v.admit ? "OK" : v.reason,
                                             v.user_id, ""});
  }
}

void ZapHandler::log_refusal(const std::string& address, const std::string& who, const std::string& reason) {
  // A refused peer retries every few hundred ms: one line a minute per peer.
  const auto now = std::chrono::steady_clock::now();
  if (last_logged_.size() > 10000) last_logged_.clear();  // many forged keys must not grow memory
  auto& last = last_logged_[address + "/" + who];
  if (last.time_since_epoch().count() != 0 && now - last < std::chrono::minutes(1)) return;
  last = now;
  if (log_) log_("refused connection from " + address + ": " + reason);
}

std::string ZapHandler::name_of(const std::string& user_id) const {
  auto it = policy_.allowed.find(user_id);
  return it == policy_.allowed.end() ? "" : it->second;
}

BrokerKeys load_broker_keys(const std::string& key_file, const std::string& allow_dir, bool insecure) {
  BrokerKeys keys;
  if (key_file.empty() != allow_dir.empty())
    throw InputError(key_file.empty() ? "--allow needs --key FILE (the broker's own secret key)"
                                      : "--key needs --allow DIR (the invited workers' *.pub files)");
  if (key_file.empty()) {
    keys.policy.mode = insecure ? AdmissionMode::insecure : AdmissionMode::protected_loopback;
    return keys;
  }
  if (insecure) throw InputError("--insecure contradicts --key/--allow");
  keys.own = protocol::load_secret_key(key_file);
  keys.policy.mode = AdmissionMode::keyed;
  keys.policy.allowed = protocol::load_allowed_keys(allow_dir);
  return keys;
}

void secure_broker_socket(zmq::socket_t& socket, const BrokerKeys& keys) {
  if (keys.own) protocol::make_curve_server(socket, *keys.own);
  if (keys.policy.mode != AdmissionMode::insecure) socket.set(zmq::sockopt::zap_domain, kZapDomain);
}

std::string admission_banner(const BrokerKeys& keys, const std::string& endpoint) {
  switch (keys.policy.mode) {
    case AdmissionMode::keyed:
      return "CURVE: admitting " + std::to_string(keys.policy.allowed.size()) +
             " invited worker key(s); broker public key " + keys.own->public_key;
    case AdmissionMode::protected_loopback:
      return "WARNING: no --key/--allow: this farm is UNAUTHENTICATED and admits only peers on this machine "
             "(loopback). To admit other machines, invite their keys (rayfarm keygen; --key FILE --allow DIR), "
             "or pass --insecure.";
    case AdmissionMode::insecure:
      return "WARNING: --insecure: this farm is UNAUTHENTICATED; ANY host that can reach " + endpoint +
             " can join, read the scene and write pixels into the image.";
  }
  return "";
}

}  // namespace rayfarm
