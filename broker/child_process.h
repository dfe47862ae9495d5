// ChildProcess: a `rayfarm worker` (or any program) started with fork/exec and
// owned by this object. The child gets SIGKILL if the parent dies
// (PR_SET_PDEATHSIG) and the destructor kills and reaps it, so no error path
// leaves an orphan behind.
#pragma once

#include <sys/types.h>

#include <string>
#include <vector>

namespace rayfarm {

class ChildProcess {
 public:
  // Starts `exe` with `args` (argv[1...]); stdout/stderr are inherited.
  ChildProcess(const std::string& exe, const std::vector<std::string>& args);
  ~ChildProcess();  // kill(SIGKILL) + reap if still running
  ChildProcess(ChildProcess&& o) noexcept;
  ChildProcess& operator=(ChildProcess&&) = delete;
  ChildProcess(const ChildProcess&) = delete;

  pid_t pid() const { return pid_; }
  // True while running; reaps without blocking.
  bool running();
  // Exit status once reaped (waitpid status), -1 while running.
  int status() const { return status_; }
  void kill(int signal);
  // Waits up to `timeout_s` for exit; false if it is still running.
  bool wait_for(double timeout_s);

 private:
  pid_t pid_ = -1;
  int status_ = -1;
};

// Waits up to `grace_s` in all for every child to exit, then kills (SIGKILL)
// those still running: one grace period shared, not one each, so that wedged
// children (stopped, hung) hold the caller `grace_s`, not `grace_s` apiece.
void wait_for_all_or_kill(std::vector<ChildProcess>& children, double grace_s);

// The running executable (/proc/self/exe), used to start worker processes.
std::string self_executable();

// Describes a waitpid status: "exit code 1", "killed by signal 9".
std::string describe_status(int status);

}  // namespace rayfarm
