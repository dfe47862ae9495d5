// The open-file budget of a process that holds a connection or two for every
// worker: the soft RLIMIT_NOFILE (often 1024) is raised before the sockets
// exist, so that a large farm fails at once with a message naming the limit,
// not midway with "Too many open files" or, worse, with workers that can
// never connect and a broker that waits for them.
#pragma once

#include <cstddef>
#include <string>

namespace rayfarm {

// Raises the soft RLIMIT_NOFILE to the hard limit if fewer than `needed`
// files may be open. Throws InputError "WHAT needs about N open files, but
// this process may open at most M (RLIMIT_NOFILE hard limit; see `ulimit
// -Hn`): ADVICE" when even the hard limit is too low.
void reserve_open_files(size_t needed, const std::string& what, const std::string& advice);

// For a process that takes whatever connects, unknown in number (a networked
// broker): raises the soft RLIMIT_NOFILE to the hard limit, then as
// reserve_open_files for the `needed` files it must have at least.
void open_files_up_to_hard_limit(size_t needed, const std::string& what, const std::string& advice);

}  // namespace rayfarm
