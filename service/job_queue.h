// JobQueue: the order and state of the service's jobs, pure logic (no files,
// no sockets), so its rules are tested on their own. Jobs run one at a time in
// submission order; a higher priority jumps ahead of every queued job of lower
// priority (never ahead of the running one). A job of several frames stays
// `running` from its first frame to its last. States: queued -> running ->
// done | failed; queued or running -> cancelled. Finished states are final.
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace rayfarm {

// An Idempotency-Key (docs/api.md) is 1 to this many printable ASCII characters.
inline constexpr size_t kMaxIdempotencyKey = 255;

enum class JobState { queued, running, done, failed, cancelled };

const char* job_state_name(JobState s);
// Throws InputError for an unknown name.
JobState job_state_from_name(const std::string& name);
bool is_finished(JobState s);

// What the queue knows of a job; rows count every frame of the job.
struct JobStatus {
  uint64_t id = 0;
  int priority = 0;
  uint64_t order = 0;  // submission order; lower = earlier
  JobState state = JobState::queued;
  int frames = 1;
  int frames_done = 0;
  // 64 bits: a job of 100,000 frames 65,536 rows high has 6.5e9 rows.
  int64_t rows_done = 0;
  int64_t rows_total = 0;
  int64_t resumed_rows = 0;     // restored from the journal after a restart
  int64_t rerendered_rows = 0;  // rendered again, their first result lost (lost tasks, in flight at a crash)
  std::string error;        // failed/cancelled: why
  // The Idempotency-Key it was submitted with and the hash of that request's
  // body (docs/api.md), kept in its status.json; "" for none.
  std::string idempotency_key, body_hash;
};

class JobQueue {
 public:
  // Adds a job in any state (a restart re-adds finished ones too); its id must be new.
  void add(const JobStatus& job);

  // The running job if there is one, else the queued job that runs next.
  std::optional<uint64_t> next() const;
  // The queued job that would run after `current` (for announcing it early).
  std::optional<uint64_t> after(uint64_t current) const;

  // queued -> running.
  void start(uint64_t id);
  // running: `frames_done` + 1; the last frame makes it done.
  void frame_done(uint64_t id);
  void fail(uint64_t id, const std::string& reason);
  // Returns false if the job had already finished (then nothing changes).
  bool cancel(uint64_t id, const std::string& reason = "cancelled by request");

  // Puts a job's status back as it was before a change that could not be
  // saved (the caller's copy from get()): the queue says what the folder says.
  void put_back(const JobStatus& before);

  void add_rows(uint64_t id, int64_t rows, bool resumed = false);
  void add_rerendered(uint64_t id, int64_t rows);

  bool contains(uint64_t id) const { return jobs_.count(id) > 0; }
  // Throws std::out_of_range for an unknown id.
  const JobStatus& get(uint64_t id) const { return jobs_.at(id); }
  // All jobs, submission order.
  std::vector<JobStatus> list() const;
  uint64_t max_id() const { return jobs_.empty() ? 0 : jobs_.rbegin()->first; }

 private:
  JobStatus& at(uint64_t id, JobState expected);
  std::map<uint64_t, JobStatus> jobs_;
};

}  // namespace rayfarm
