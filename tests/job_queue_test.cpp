// JobQueue: submission order, priorities that jump the queue but never the
// running job, multi-frame jobs, and the final states.
#include <doctest/doctest.h>

#include <stdexcept>

#include "service/job_queue.h"

using namespace rayfarm;

namespace {

JobStatus job(uint64_t id, int priority = 0, int frames = 1) {
  JobStatus s;
  s.id = id;
  s.order = id;
  s.priority = priority;
  s.frames = frames;
  return s;
}

}  // namespace

TEST_CASE("job queue: submission order, then priority jumps the queued jobs") {
  JobQueue q;
  CHECK(!q.next());
  q.add(job(1));
  q.add(job(2));
  q.add(job(3, 5));
  CHECK(*q.next() == 3);  // priority first
  q.start(1);             // a running job keeps running whatever arrives
  CHECK(*q.next() == 1);
  CHECK(*q.after(1) == 3);
  q.frame_done(1);
  CHECK(q.get(1).state == JobState::done);
  CHECK(*q.next() == 3);
  q.start(3);
  q.frame_done(3);
  CHECK(*q.next() == 2);
  CHECK(!q.after(2));
}

TEST_CASE("job queue: a multi-frame job runs until its last frame") {
  JobQueue q;
  q.add(job(1, 0, 3));
  q.add(job(2));
  q.start(1);
  q.frame_done(1);
  q.frame_done(1);
  CHECK(q.get(1).state == JobState::running);
  CHECK(*q.next() == 1);
  q.frame_done(1);
  CHECK(q.get(1).state == JobState::done);
  CHECK(q.get(1).frames_done == 3);
  CHECK(*q.next() == 2);
}

TEST_CASE("job queue: cancel and fail are final, illegal moves are caught") {
  JobQueue q;
  q.add(job(1));
  q.add(job(2));
  CHECK(q.cancel(2));
  CHECK(q.get(2).state == JobState::cancelled);
  CHECK(!q.cancel(2));
  q.start(1);
  q.fail(1, "scene unreadable");
  CHECK(q.get(1).state == JobState::failed);
  CHECK(q.get(1).error == "scene unreadable");
  CHECK(!q.cancel(1));
  CHECK(!q.next());
  CHECK_THROWS_AS(q.start(1), std::logic_error);
  CHECK_THROWS_AS(q.add(job(1)), std::logic_error);
  CHECK_THROWS_AS(q.get(9), std::out_of_range);
}

TEST_CASE("job queue: rows and resumed rows are counted per job") {
  JobQueue q;
  q.add(job(1));
  q.add_rows(1, 10, true);
  q.add_rows(1, 5);
  q.add_rerendered(1, 2);
  CHECK(q.get(1).rows_done == 15);
  CHECK(q.get(1).resumed_rows == 10);
  CHECK(q.get(1).rerendered_rows == 2);
  CHECK(job_state_from_name("cancelled") == JobState::cancelled);
  CHECK_THROWS(job_state_from_name("paused"));
}
