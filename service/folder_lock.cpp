// The state folder's lock; see folder_lock.h.
#include "service/folder_lock.h"

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <thread>

#include "tracer/error.h"

namespace rayfarm {

FolderLock::FolderLock(const std::string& dir, std::chrono::milliseconds wait,
                       const std::function<void(const std::string&)>& on_wait, const std::atomic<bool>* stop) {
  fd_ = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd_ < 0) throw InputError(dir + ": cannot open the folder (" + std::strerror(errno) + ")");
  // A broker killed a moment ago still holds the lock until the kernel has
  // torn the process down: a restart right after kill -9 waits for that
  // rather than be refused. A broker that keeps running is refused after it.
  const auto deadline = std::chrono::steady_clock::now() + wait;
  bool said = false;
  while (::flock(fd_, LOCK_EX | LOCK_NB) != 0) {
    // A broker stopped while it waits stops as it would once serving, not
    // killed by the signal's default action.
    if (stop && *stop) {
      ::close(fd_);
      throw LockWaitStopped("while waiting for " + dir + ", locked by another broker; the folder was not taken");
    }
    if (std::chrono::steady_clock::now() >= deadline) {
      ::close(fd_);
      throw InputError(dir + ": in use by another running broker (its addresses and pid are in " + dir +
                       "/service.json); a state folder serves one broker at a time");
    }
    if (!said && on_wait)
      on_wait(dir + ": locked by another broker; waiting up to " + std::to_string(wait.count()) +
              " ms for it to exit (a broker killed a moment ago still holds it)");
    said = true;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
}

FolderLock::~FolderLock() { ::close(fd_); }

}  // namespace rayfarm
