// FolderLock: one process at a time in a folder. The service's state folder is
// its memory; two brokers on one folder would hand out the same job ids and
// overwrite each other's jobs and journals. The lock is flock(2) on the folder
// itself, held while the FolderLock lives; the kernel drops it when the process
// dies, so a restart after kill -9 takes the folder again at once.
#pragma once

#include <string>

namespace rayfarm {

class FolderLock {
 public:
  // Locks `dir` (which must exist) or throws InputError "DIR: in use by another
  // running broker ..." while another FolderLock, in any process, holds it.
  explicit FolderLock(const std::string& dir);
  ~FolderLock();
  FolderLock(const FolderLock&) = delete;
  FolderLock& operator=(const FolderLock&) = delete;

 private:
  int fd_ = -1;
};

}  // namespace rayfarm
