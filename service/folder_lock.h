// FolderLock: one process at a time in a folder. The service's state folder is
// its memory; two brokers on one folder would hand out the same job ids and
// overwrite each other's jobs and journals. The lock is flock(2) on the folder
// itself, held while the FolderLock lives; the kernel drops it when the process
// dies, so a restart after kill -9 takes the folder again -- once the dying
// process is gone, which can take a few milliseconds after the kill: a lock
// held is waited for a short while before the folder is refused.
#pragma once

#include <atomic>
#include <chrono>
#include <functional>
#include <stdexcept>
#include <string>

namespace rayfarm {

inline constexpr std::chrono::milliseconds kFolderLockWait{2000};

// The wait for a held lock given up because the process was told to stop (a
// stop signal, tracer/stop_signals.h): the folder was not taken.
struct LockWaitStopped : std::runtime_error {
  using std::runtime_error::runtime_error;
};

class FolderLock {
 public:
  // Locks `dir` (which must exist) or throws InputError "DIR: in use by another
  // running broker ..." while another FolderLock, in any process, holds it
  // for longer than `wait`. `on_wait` ({} = silent) hears once that the wait began.
  // `stop` (if given) turning true ends the wait with LockWaitStopped.
  explicit FolderLock(const std::string& dir, std::chrono::milliseconds wait = kFolderLockWait,
                      const std::function<void(const std::string&)>& on_wait = {},
                      const std::atomic<bool>* stop = nullptr);
  ~FolderLock();
  FolderLock(const FolderLock&) = delete;
  FolderLock& operator=(const FolderLock&) = delete;

 private:
  int fd_ = -1;
};

}  // namespace rayfarm
