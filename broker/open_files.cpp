// Raising the open-file limit; see open_files.h.
#include "broker/open_files.h"

#include <sys/resource.h>

#include "tracer/error.h"

namespace rayfarm {

void reserve_open_files(size_t needed_files, const std::string& what, const std::string& advice) {
  const rlim_t needed = static_cast<rlim_t>(needed_files);
  rlimit limit{};
  if (getrlimit(RLIMIT_NOFILE, &limit) != 0) return;
  if (limit.rlim_cur != RLIM_INFINITY && limit.rlim_cur >= needed) return;
  if (limit.rlim_max != RLIM_INFINITY && limit.rlim_max < needed)
    throw InputError(what + " needs about " + std::to_string(needed) +
                     " open files, but this process may open at most " + std::to_string(limit.rlim_max) +
                     " (RLIMIT_NOFILE hard limit; see `ulimit -Hn`): " + advice);
  limit.rlim_cur = limit.rlim_max == RLIM_INFINITY ? needed : limit.rlim_max;
  if (setrlimit(RLIMIT_NOFILE, &limit) != 0)
    throw InputError("cannot raise RLIMIT_NOFILE to " + std::to_string(limit.rlim_cur) + " for " + what);
}

void open_files_up_to_hard_limit(size_t needed, const std::string& what, const std::string& advice) {
  reserve_open_files(needed, what, advice);
  rlimit limit{};
  if (getrlimit(RLIMIT_NOFILE, &limit) != 0 || limit.rlim_cur == limit.rlim_max) return;
  limit.rlim_cur = limit.rlim_max;
  // Not an error: the files needed are reserved, and more workers than those are a bonus.
  setrlimit(RLIMIT_NOFILE, &limit);
}

}  // namespace rayfarm
