// CURVE keys: who a farm peer is. Every worker and the broker hold a
// Curve25519 key pair (`rayfarm keygen -o NAME`: NAME.key secret, mode 0600,
// NAME.pub public), the broker admits only workers whose public key is in its
// allow folder (broker/admission.h), and every byte between them is encrypted
// and authenticated by ZeroMQ's CURVE mechanism (RFC 26). Files hold one Z85
// line (40 characters) after optional '#' comment lines.
#pragma once

#include <map>
#include <string>

#include <zmq.hpp>

namespace rayfarm::protocol {

struct CurveKeyPair {
  std::string public_key;  // Z85, 40 characters
  std::string secret_key;  // Z85, 40 characters
};

// Throws InputError unless this libzmq was built with CURVE (libsodium).
void require_curve();

CurveKeyPair generate_curve_keypair();

// Writes NAME.key (mode 0600) and NAME.pub; never overwrites an existing file,
// and refuses a NAME without a file name ("", "DIR/") or ending in .key or .pub.
// Returns the pair written.
CurveKeyPair write_key_files(const std::string& name);

// A secret key file (NAME.key); the public half is derived from it. Refuses a
// file that others may read, as ssh does, and keygen's public key files (and
// load_public_key its secret ones). InputError names the file.
CurveKeyPair load_secret_key(const std::string& path);

// A public key file (NAME.pub): its Z85 key.
std::string load_public_key(const std::string& path);

// Every *.pub in `dir`: Z85 key -> name (the file's stem, e.g. "render-07").
// Throws InputError if the folder has none, or if others may write it, a
// *.pub in it, or a folder above it (one not sticky, or not owned by root or
// this user), as ssh refuses an authorized_keys others could replace.
std::map<std::string, std::string> load_allowed_keys(const std::string& dir);

// Socket options for the two ends of a CURVE connection; set before bind/connect.
void make_curve_server(zmq::socket_t& socket, const CurveKeyPair& own);
void make_curve_client(zmq::socket_t& socket, const CurveKeyPair& own, const std::string& server_public_key);

}  // namespace rayfarm::protocol
