// Checked, atomic output files; see output_file.h.
#include "tracer/output_file.h"

#include <fcntl.h>
#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <climits>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <utility>

#include "tracer/error.h"

namespace rayfarm {
namespace {

namespace fs = std::filesystem;

// The longest file name (not path) the file systems rayfarm writes to take.
constexpr size_t kMaxFileNameBytes = NAME_MAX;

// NAME cut to at most `bytes`, keeping its extension, and never inside a
// UTF-8 character: "long...name.png" -> "long...na.png".
std::string shortened_name(const std::string& name, const std::string& ext, size_t bytes) {
  if (name.size() <= bytes) return name;
  size_t head = bytes > ext.size() ? bytes - ext.size() : 0;
  while (head > 0 && (static_cast<unsigned char>(name[head]) & 0xC0) == 0x80) --head;  // a continuation byte
  return name.substr(0, head) + ext;
}

// ".NAME.ID.tmp.EXT" for NAME.EXT, ID being the writer's "PID-N": hidden,
// unique per process and call, saying whose it is, and still ending in the
// extension. NAME is shortened when the temporary's name would pass the file
// system's limit: a NAME.EXT of 240 bytes is a valid output, and its
// temporary, some 20 bytes longer, was refused ("File name too long"),
// failing the render.
std::string temp_name(const std::string& name, const std::string& ext, const std::string& id) {
  const std::string suffix = "." + id + ".tmp" + ext;
  const size_t room = kMaxFileNameBytes - std::min(kMaxFileNameBytes, 1 + suffix.size());
  return "." + shortened_name(name, ext, room) + suffix;
}

std::string temp_path_for(const std::string& path) {
  static std::atomic<unsigned> counter{0};
  const fs::path p(path);
  const std::string id = std::to_string(getpid()) + "-" + std::to_string(counter++);
  return (p.parent_path() / temp_name(p.filename().string(), p.extension().string(), id)).string();
}

bool all_digits(const std::string& s) {
  return !s.empty() && std::all_of(s.begin(), s.end(), [](char c) { return c >= '0' && c <= '9'; });
}

// The writer's PID if `file` is a temporary of NAME.EXT, exactly as
// temp_name() names one; 0 for any other file.
pid_t writer_of(const std::string& file, const std::string& name, const std::string& ext) {
  const std::string tail = ".tmp" + ext;
  if (file.size() <= tail.size() || file.compare(file.size() - tail.size(), tail.size(), tail) != 0) return 0;
  const std::string head = file.substr(0, file.size() - tail.size());
  const std::string id = head.substr(head.rfind('.') + 1);  // "PID-N"
  const size_t dash = id.find('-');
  if (dash == std::string::npos || dash > 9 || id[0] == '0') return 0;  // a PID as getpid() gives it
  const std::string pid = id.substr(0, dash);
  if (!all_digits(pid) || !all_digits(id.substr(dash + 1)) || temp_name(name, ext, id) != file) return 0;
  return static_cast<pid_t>(std::stol(pid));
}

// kill(2) with no signal fails with ESRCH only when no process has the PID;
// EPERM is another user's process, alive.
bool process_gone(pid_t pid) { return ::kill(pid, 0) != 0 && errno == ESRCH; }

// A writer killed by SIGKILL (or a crash, a power cut) leaves its temporary
// behind, as large as the file, and nothing else would ever remove it.
// Best effort: a folder that cannot be read is the writer's error to report.
void remove_stale_temporaries(const std::string& target) {
  const fs::path p(target);
  const fs::path dir = p.has_parent_path() ? p.parent_path() : fs::path(".");
  const std::string name = p.filename().string(), ext = p.extension().string();
  std::error_code ec;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    const pid_t pid = writer_of(it->path().filename().string(), name, ext);
    std::error_code type_ec;
    if (pid > 0 && it->symlink_status(type_ec).type() == fs::file_type::regular && process_gone(pid))
      ::unlink(it->path().c_str());
  }
}

std::string errno_text() { return std::strerror(errno); }

void sync_file(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) throw InputError(path + ": cannot write (" + errno_text() + ")");
  const int rc = ::fsync(fd);
  ::close(fd);
  if (rc != 0) throw InputError(path + ": cannot write (fsync: " + errno_text() + ")");
}

// Creates and removes a file beside `path`; throws "name: cannot write (reason)".
void create_probe_beside(const std::string& path, const std::string& name) {
  const std::string probe = temp_path_for(path);
  const RemovedOnInterrupt removed_on_interrupt(probe);
  const int fd = ::open(probe.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
  if (fd < 0) throw InputError(name + ": cannot write (" + errno_text() + ")");
  ::close(fd);
  ::unlink(probe.c_str());
}

// An existing device, FIFO or socket (say -o /dev/null) would be replaced by
// the rename, not written to: the node itself would be gone. Symlinks are
// followed, so -o /dev/stdout is caught too.
void refuse_special_file(const std::string& path) {
  std::error_code ec;
  const fs::file_status status = fs::status(path, ec);
  if (ec || !fs::exists(status) || fs::is_regular_file(status) || fs::is_directory(status)) return;
  throw InputError(path + ": cannot write (not a regular file: output is written beside it and renamed over it)");
}

// A symlink is written through: renamed over, the link itself became a file
// and the file it points to kept the old contents.
std::string link_target(const std::string& path) {
  std::error_code ec;
  if (!fs::is_symlink(path, ec)) return path;
  const fs::path target = fs::weakly_canonical(path, ec);
  return ec ? path : target.string();
}

}  // namespace

void check_output_path(const std::string& path) {
  if (path.empty()) throw InputError("output path is empty");
  const fs::path dir = fs::path(path).parent_path();
  std::error_code ec;
  if (!dir.empty() && !fs::is_directory(dir, ec))
    throw InputError(path + ": cannot write (no directory " + dir.string() + ")");
  if (fs::is_directory(path, ec)) throw InputError(path + ": cannot write (it is a directory)");
  refuse_special_file(path);
  create_probe_beside(link_target(path), path);
}

void check_distinct_files(const std::vector<std::pair<std::string, std::string>>& files) {
  std::error_code ec;
  std::vector<fs::path> seen;
  for (size_t i = 0; i < files.size(); ++i) {
    const auto& [option, path] = files[i];
    seen.push_back(path.empty() ? fs::path() : fs::weakly_canonical(path, ec));
    if (ec) seen.back() = fs::absolute(path).lexically_normal();
    for (size_t j = 0; j < i; ++j)
      if (!path.empty() && seen[j] == seen[i])
        throw InputError(option + " " + path + " is the same file as " + files[j].first);
  }
}

void check_output_folder(const std::string& dir) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) throw InputError(dir + ": cannot create folder (" + ec.message() + ")");
  create_probe_beside((fs::path(dir) / "probe").string(), dir);
}

AtomicOutputFile::AtomicOutputFile(std::string path)
    : path_(std::move(path)), target_(link_target(path_)), temp_(temp_path_for(target_)) {
  refuse_special_file(path_);  // for writers that skipped check_output_path
  remove_stale_temporaries(target_);
}

AtomicOutputFile::~AtomicOutputFile() {
  if (!committed_) ::unlink(temp_.c_str());
}

void AtomicOutputFile::commit() {
  try {
    sync_file(temp_);
  } catch (const InputError& e) {
    throw naming_path(e);
  }
  if (std::rename(temp_.c_str(), target_.c_str()) != 0)
    throw InputError(path_ + ": cannot write (rename: " + errno_text() + ")");
  committed_ = true;
  removed_on_interrupt_.forget();
}

InputError AtomicOutputFile::naming_path(const InputError& error) const {
  std::string message = error.what();
  for (size_t at; (at = message.find(temp_)) != std::string::npos;) message.replace(at, temp_.size(), path_);
  return InputError(message);
}

void write_atomically(const std::string& path, const std::function<void(const std::string& temp)>& write) {
  AtomicOutputFile file(path);
  try {
    write(file.temp_path());
  } catch (const InputError& e) {
    throw file.naming_path(e);
  }
  file.commit();
}

}  // namespace rayfarm
