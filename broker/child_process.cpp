// Owned child processes; see child_process.h.
#include "broker/child_process.h"

#include <signal.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <climits>
#include <cstring>
#include <thread>

#include "tracer/error.h"
#include "tracer/executable_path.h"

namespace rayfarm {

ChildProcess::ChildProcess(const std::string& exe, const std::vector<std::string>& args) {
  std::vector<std::string> argv_strings = {exe};
  argv_strings.insert(argv_strings.end(), args.begin(), args.end());
  std::vector<char*> argv;
  for (auto& s : argv_strings) argv.push_back(s.data());
  argv.push_back(nullptr);
  const pid_t parent = getpid();
  pid_ = fork();
  if (pid_ < 0) throw std::runtime_error(std::string("fork failed: ") + std::strerror(errno));
  if (pid_ == 0) {
    // Child: die with the parent, even if it is killed with SIGKILL.
    prctl(PR_SET_PDEATHSIG, SIGKILL);
    if (getppid() != parent) _exit(127);  // the parent already died before prctl
    execv(exe.c_str(), argv.data());
    std::fprintf(stderr, "rayfarm: cannot run %s: %s\n", exe.c_str(), std::strerror(errno));
    _exit(127);
  }
}

ChildProcess::ChildProcess(ChildProcess&& o) noexcept : pid_(o.pid_), status_(o.status_) { o.pid_ = -1; }

ChildProcess::~ChildProcess() {
  if (pid_ > 0 && running()) {
    ::kill(pid_, SIGKILL);
    int st = 0;
    waitpid(pid_, &st, 0);
  }
}

bool ChildProcess::running() {
  if (pid_ <= 0 || status_ >= 0) return false;
  int st = 0;
  const pid_t r = waitpid(pid_, &st, WNOHANG);
  if (r == pid_) {
    status_ = st;
    return false;
  }
  return r == 0;
}

void ChildProcess::kill(int signal) {
  if (running()) ::kill(pid_, signal);
}

bool ChildProcess::wait_for(double timeout_s) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  while (running()) {
    if (std::chrono::steady_clock::now() >= end) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return true;
}

void wait_for_all_or_kill(std::vector<ChildProcess>& children, double grace_s) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(grace_s);
  for (ChildProcess& c : children) {
    const double left = std::chrono::duration<double>(end - std::chrono::steady_clock::now()).count();
    if (!c.wait_for(std::max(0.0, left))) c.kill(SIGKILL);
  }
}

std::string self_executable() {
  std::string path = executable_path();
  if (path.empty()) throw std::runtime_error("cannot read /proc/self/exe");
  return path;
}

std::string describe_status(int status) {
  if (status < 0) return "running";
  if (WIFEXITED(status)) return "exit code " + std::to_string(WEXITSTATUS(status));
  if (WIFSIGNALED(status)) return "killed by signal " + std::to_string(WTERMSIG(status));
  return "status " + std::to_string(status);
}

}  // namespace rayfarm
