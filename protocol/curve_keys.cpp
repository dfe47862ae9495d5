// CURVE key files and socket options; see curve_keys.h.
#include "protocol/curve_keys.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <sstream>
#include <vector>

#include "protocol/config_file.h"
#include "tracer/error.h"
#include "tracer/text_file.h"

namespace rayfarm::protocol {
namespace {

namespace fs = std::filesystem;

constexpr size_t kZ85KeyChars = 40;  // a 32-byte key in Z85

bool is_z85_key(const std::string& text) {
  if (text.size() != kZ85KeyChars) return false;
  uint8_t bytes[32];
  return zmq_z85_decode(bytes, text.c_str()) != nullptr;
}

// What a key file held instead of one key: a file cut short in a copy
// shows as a short line, a pasted pair as two lines.
std::string what_was_found(int lines, const std::string& last_line) {
  if (lines == 0) return "no key line (only comments or blank lines)";
  if (lines > 1) return std::to_string(lines) + " non-comment lines";
  if (last_line.size() != kZ85KeyChars) return "a line of " + std::to_string(last_line.size()) + " characters";
  return "40 characters that are not Z85";
}

constexpr char kSecretHeader[] = "# rayfarm CURVE secret key";
constexpr char kPublicHeader[] = "# rayfarm CURVE public key";

// The one non-comment line of a key file. Both halves are 40 Z85 characters,
// so a swapped file would load and fail later as a handshake that never
// completes; the header keygen writes tells them apart here.
std::string read_key_line(const std::string& path, bool secret) {
  std::istringstream in(read_text_file(path, kMaxConfigBytes));
  std::string line, key;
  int lines = 0;
  while (std::getline(in, line)) {
    while (!line.empty() && (line.back() == '\r' || line.back() == ' ')) line.pop_back();
    if (secret && line.rfind(kPublicHeader, 0) == 0)
      throw InputError(path + ": is a public key (NAME.pub); give the secret key file, NAME.key");
    if (!secret && line.rfind(kSecretHeader, 0) == 0)
      throw InputError(path + ": is a secret key (NAME.key); give its public key file, NAME.pub, and keep this one "
                              "on its own machine");
    if (line.empty() || line[0] == '#') continue;
    key = line;
    ++lines;
  }
  if (lines != 1 || !is_z85_key(key))
    throw InputError(path + ": expected one 40-character Z85 CURVE key (from `rayfarm keygen`), found " +
                     what_was_found(lines, key));
  return key;
}

// Errors begin with the key NAME the user gave (`keygen -o NAME`), so that
// the command line names its option: they began with NAME.key, a path the
// user never typed.
void write_new_file(const std::string& name, const std::string& path, const std::string& text, mode_t mode) {
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, mode);
  if (fd < 0) throw InputError(name + ": cannot create " + path + " (" + std::strerror(errno) + ")");
  const bool ok = ::write(fd, text.data(), text.size()) == static_cast<ssize_t>(text.size()) && ::fsync(fd) == 0;
  const int write_errno = errno;
  ::close(fd);
  if (!ok) throw InputError(name + ": cannot write " + path + " (" + std::strerror(write_errno) + ")");
}

// Whoever may write the allow folder or a *.pub in it may invite a key of
// their own, so both must be writable by their owner alone, as ssh requires of
// authorized_keys.
void require_owner_writable_only(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) == 0 && (st.st_mode & (S_IWGRP | S_IWOTH)) != 0)
    throw InputError(path + ": writable by others, who could invite a worker key of their own; run `chmod go-w " +
                     path + "`");
}

// Whoever may rename a folder above the allow folder may put a folder of
// their own, with their own *.pub, in its place: as ssh requires of the
// folders above authorized_keys, each one up to / must be owned by root or
// the broker's user and writable by its owner alone, or sticky (/tmp: there
// others may add their own entries but not rename another's).
void require_trusted_parents(const std::string& dir) {
  std::error_code ec;
  const fs::path real = fs::canonical(dir, ec);  // the folder a link names: its parents are the ones read through
  if (ec) return;  // gone meanwhile: reading it says so
  for (fs::path p = real.parent_path(); !p.empty(); p = p.parent_path()) {
    struct stat st {};
    if (::stat(p.c_str(), &st) != 0) break;
    const std::string above = p.string() + ": a folder above the allow folder " + dir;
    if (st.st_uid != 0 && st.st_uid != ::geteuid())
      throw InputError(above + " is owned by uid " + std::to_string(st.st_uid) + ", neither root nor this broker's " +
                       "user, who could put keys of their own in its place; give it to root or to this user");
    if ((st.st_mode & (S_IWGRP | S_IWOTH)) != 0 && (st.st_mode & S_ISVTX) == 0)
      throw InputError(above + " is writable by others, who could put keys of their own in its place; run `chmod " +
                       "go-w " + p.string() + "`");
    if (p == p.root_path()) break;
  }
}

}  // namespace

void require_curve() {
  if (!zmq_has("curve"))
    throw InputError("this libzmq was built without CURVE security (libsodium); keys cannot be used");
}

CurveKeyPair generate_curve_keypair() {
  require_curve();
  char pub[41], sec[41];
  if (zmq_curve_keypair(pub, sec) != 0) throw zmq::error_t();
  return {pub, sec};
}

CurveKeyPair write_key_files(const std::string& name) {
  // "DIR/" or "" would write the hidden DIR/.key and DIR/.pub, and an allow
  // folder reads no '.pub' without a stem.
  const std::string stem = fs::path(name).filename().string();
  std::error_code ec;
  if (stem.empty() || stem == "." || stem == ".." || fs::is_directory(name, ec))
    throw InputError("'" + name + "': not a key name; give one such as DIR/render-07 (writes render-07.key and .pub)");
  // "-o head.key" would write head.key.key and head.key.pub, and a broker
  // then told "--key head.key" reads no key at all.
  const std::string ext = fs::path(name).extension().string();
  if (ext == ".key" || ext == ".pub")
    throw InputError("'" + name + "': give the name without " + ext + " (it writes NAME.key and NAME.pub)");
  const std::string key_path = name + ".key", pub_path = name + ".pub";
  // Said of the folder: "nodir/k.key: cannot create (No such file or directory)" named neither it nor the option.
  const fs::path dir = fs::path(name).parent_path();
  if (!dir.empty() && !fs::is_directory(dir, ec))
    throw InputError(name + ": cannot write " + key_path + " (no directory " + dir.string() + ")");
  const CurveKeyPair pair = generate_curve_keypair();
  // symlink_status: a dangling link is there too, and creating through it fails.
  for (const std::string& p : {key_path, pub_path})
    if (fs::exists(fs::symlink_status(p, ec)))
      throw InputError(name + ": " + p + " exists; not overwritten (remove it first)");
  write_new_file(name, key_path,
                 std::string(kSecretHeader) + ": keep it private (mode 0600)\n" + pair.secret_key + "\n", 0600);
  try {
    write_new_file(name, pub_path, std::string(kPublicHeader) + "\n" + pair.public_key + "\n", 0644);
  } catch (const InputError&) {
    // A secret without its public half is of no use, and left behind it
    // makes the next `keygen -o NAME` refuse to run.
    fs::remove(key_path, ec);
    throw;
  }
  return pair;
}

CurveKeyPair load_secret_key(const std::string& path) {
  require_curve();
  CurveKeyPair pair;
  pair.secret_key = read_key_line(path, true);  // first: `chmod 600` is no advice for a public key given here
  struct stat st {};
  if (::stat(path.c_str(), &st) == 0 && (st.st_mode & 077) != 0)
    throw InputError(path + ": secret key is readable by others; run `chmod 600 " + path + "`");
  char pub[41];
  if (zmq_curve_public(pub, pair.secret_key.c_str()) != 0) throw InputError(path + ": not a CURVE secret key");
  pair.public_key = pub;
  return pair;
}

std::string load_public_key(const std::string& path) { return read_key_line(path, false); }

std::map<std::string, std::string> load_allowed_keys(const std::string& dir) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) throw InputError(dir + ": not a folder (expected a folder of *.pub files)");
  require_trusted_parents(dir);
  require_owner_writable_only(dir);
  std::vector<fs::path> files;
  for (const auto& entry : fs::directory_iterator(dir))
    if (entry.path().extension() == ".pub") files.push_back(entry.path());
  std::sort(files.begin(), files.end());  // the same file named first in any refusal below
  std::map<std::string, std::string> keys;
  std::map<std::string, std::string> file_of;  // key -> the file it was read from
  for (const fs::path& file : files) {
    const std::string key = load_public_key(file.string());
    require_owner_writable_only(file.string());
    // One key is one worker, named by its file: a second file holding it left
    // the worker's name to the order the folder was listed in.
    if (const auto [it, added] = file_of.emplace(key, file.string()); !added)
      throw InputError(file.string() + ": holds the same key as " + it->second + "; keep one file a worker key");
    keys[key] = file.stem().string();
  }
  if (keys.empty()) throw InputError(dir + ": no *.pub files; no worker could join");
  return keys;
}

void make_curve_server(zmq::socket_t& socket, const CurveKeyPair& own) {
  socket.set(zmq::sockopt::curve_server, true);
  socket.set(zmq::sockopt::curve_secretkey, own.secret_key);
}

void make_curve_client(zmq::socket_t& socket, const CurveKeyPair& own, const std::string& server_public_key) {
  socket.set(zmq::sockopt::curve_serverkey, server_public_key);
  socket.set(zmq::sockopt::curve_publickey, own.public_key);
  socket.set(zmq::sockopt::curve_secretkey, own.secret_key);
}

}  // namespace rayfarm::protocol
