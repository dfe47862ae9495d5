// ChildProcess tests: real fork/exec of small system programs.
#include <doctest/doctest.h>

#include <chrono>
#include <string>
#include <vector>

#include "broker/child_process.h"

using namespace rayfarm;

TEST_CASE("child process: wedged children share one grace period, then are killed, and one that exits is not") {
  std::vector<ChildProcess> children;
  children.emplace_back("/bin/true", std::vector<std::string>{});
  for (int i = 0; i < 3; ++i) children.emplace_back("/bin/sleep", std::vector<std::string>{"30"});
  const auto start = std::chrono::steady_clock::now();
  wait_for_all_or_kill(children, 1.0);
  // A grace period each would take 3 s: a finished render waited so on stopped workers.
  CHECK(std::chrono::steady_clock::now() - start < std::chrono::milliseconds(2500));
  REQUIRE(children[0].wait_for(5));
  CHECK(describe_status(children[0].status()) == "exit code 0");
  for (size_t i = 1; i < children.size(); ++i) {
    REQUIRE(children[i].wait_for(5));
    CHECK(describe_status(children[i].status()) == "killed by signal 9");
  }
}
