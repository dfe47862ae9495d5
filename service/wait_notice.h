// WaitNotice: says, while a wait lasts, that it lasts. A client command
// blocked on the broker's answer (a stopped or swamped broker may leave it
// silent for the whole --timeout, five minutes for a submission) tells the
// user once the wait is long, then at growing intervals, what it waits for.
#pragma once

#include <chrono>
#include <condition_variable>
#include <functional>
#include <mutex>
#include <optional>
#include <thread>

namespace rayfarm {

// When a wait of up to `limit` is said: first at first_notice(limit), then
// each time the wait has doubled, never at or past `limit` (there the waiter
// gives up and says so itself, so no notice stands beside that line).
class NoticeSchedule {
 public:
  explicit NoticeSchedule(std::chrono::milliseconds limit);
  // The next mark, the time waited at which to say so; none once the next
  // would reach the limit.
  std::optional<std::chrono::milliseconds> next() const;
  void advance() { mark_ *= 2; }

 private:
  std::chrono::milliseconds mark_, limit_;
};

// 5 s, or half the limit when that is shorter. A healthy broker answers a
// status or a cancel in milliseconds and a submission of ordinary scenes in
// well under a second, so an answer past 5 s is no quick answer gone slow
// but a broker stopped, hung, or busy with something big; and 5 s is about
// when a person at a terminal starts to take a silent command for hung.
// Half a shorter --timeout still tells what is awaited before giving up.
std::chrono::milliseconds first_notice(std::chrono::milliseconds limit);

// Calls `tell(mark)` at each mark of the schedule while the wait lasts, from
// a thread of its own: the wait is a blocking call (the HTTP library's)
// that offers no hook while it waits for an answer's first byte, and a
// thread sleeping on a condition variable wakes for the marks and for the
// end of the wait alike, costing nothing on a quick answer.
class WaitNotice {
 public:
  WaitNotice(NoticeSchedule schedule, std::function<void(std::chrono::milliseconds)> tell);
  ~WaitNotice() { stop(); }
  WaitNotice(const WaitNotice&) = delete;
  WaitNotice& operator=(const WaitNotice&) = delete;

  // The wait is over: once this returns, nothing more is told (a notice
  // being told is finished first), so none follows what the waiter says next.
  void stop();

 private:
  void watch(NoticeSchedule schedule);

  std::function<void(std::chrono::milliseconds)> tell_;
  std::mutex mutex_;
  std::condition_variable wake_;
  bool stopped_ = false;
  std::thread thread_;
};

}  // namespace rayfarm
