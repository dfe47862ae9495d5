// When a long wait is said (service/wait_notice.h): its marks, and nothing
// said of a wait that ends before the first.
#include <doctest/doctest.h>

#include <atomic>
#include <vector>

#include "service/wait_notice.h"

using namespace rayfarm;
using std::chrono::milliseconds;
using std::chrono::seconds;

namespace {

std::vector<milliseconds> marks(milliseconds limit) {
  std::vector<milliseconds> all;
  NoticeSchedule schedule(limit);
  for (auto mark = schedule.next(); mark; schedule.advance(), mark = schedule.next()) all.push_back(*mark);
  return all;
}

}  // namespace

TEST_CASE("wait notice: first at 5 s or half a shorter wait, then each time the wait doubles, none at its end") {
  // A submission's 5 minutes: said at 5 s, 10 s, ... 160 s; at 300 s the client gives up and says so.
  CHECK(marks(seconds(300)) == std::vector<milliseconds>{seconds(5), seconds(10), seconds(20), seconds(40),
                                                         seconds(80), seconds(160)});
  CHECK(marks(seconds(20)) == std::vector<milliseconds>{seconds(5), seconds(10)});
  CHECK(marks(seconds(10)) == std::vector<milliseconds>{seconds(5)});  // a status's: once, at half
  CHECK(marks(seconds(1)) == std::vector<milliseconds>{milliseconds(500)});  // --timeout 1 still says it
  CHECK(marks(milliseconds(1)).empty());
  CHECK(marks(milliseconds(0)).empty());
}

TEST_CASE("wait notice: a wait over before its first mark says nothing, and nothing after it is over") {
  std::atomic<int> told{0};
  {
    WaitNotice waiting(NoticeSchedule(seconds(300)), [&told](milliseconds) { ++told; });
    waiting.stop();
    waiting.stop();  // the destructor stops it once more
  }
  CHECK(told == 0);
}
