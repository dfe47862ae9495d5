// The state folder's lock; see folder_lock.h.
#include "service/folder_lock.h"

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "tracer/error.h"

namespace rayfarm {

FolderLock::FolderLock(const std::string& dir) {
  fd_ = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd_ < 0) throw InputError(dir + ": cannot open the folder (" + std::strerror(errno) + ")");
  if (::flock(fd_, LOCK_EX | LOCK_NB) != 0) {
    ::close(fd_);
    throw InputError(dir + ": in use by another running broker (its addresses and pid are in " + dir +
                     "/service.json); a state folder serves one broker at a time");
  }
}

FolderLock::~FolderLock() { ::close(fd_); }

}  // namespace rayfarm
