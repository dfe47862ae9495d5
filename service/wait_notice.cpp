// Notices of a long wait; see wait_notice.h.
#include "service/wait_notice.h"

#include <algorithm>

namespace rayfarm {

using std::chrono::milliseconds;

milliseconds first_notice(milliseconds limit) { return std::min<milliseconds>(std::chrono::seconds(5), limit / 2); }

NoticeSchedule::NoticeSchedule(milliseconds limit) : mark_(first_notice(limit)), limit_(limit) {}

std::optional<milliseconds> NoticeSchedule::next() const {
  if (mark_ <= milliseconds::zero() || mark_ >= limit_) return std::nullopt;
  return mark_;
}

WaitNotice::WaitNotice(NoticeSchedule schedule, std::function<void(milliseconds)> tell)
    : tell_(std::move(tell)), thread_([this, schedule] { watch(schedule); }) {}

void WaitNotice::stop() {
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    stopped_ = true;
  }
  wake_.notify_all();
  if (thread_.joinable()) thread_.join();
}

void WaitNotice::watch(NoticeSchedule schedule) {
  const auto start = std::chrono::steady_clock::now();
  std::unique_lock<std::mutex> lock(mutex_);
  for (auto mark = schedule.next(); mark; schedule.advance(), mark = schedule.next()) {
    if (wake_.wait_until(lock, start + *mark, [this] { return stopped_; })) return;
    tell_(*mark);  // under the lock: stop() waits for it, so it never follows the waiter's next line
  }
}

}  // namespace rayfarm
