// JobService: the service's jobs, shared by the HTTP API (submit, status,
// cancel, fetch) and the broker loop (next frame, rows accepted, frame done).
// It joins the queue's rules (job_queue.h) to the state folder (job_store.h):
// every change is written before it is visible, so after a kill -9 the folder
// says what the last answer said. Thread-safe: one mutex, held briefly; the
// journal write of a row band is the longest thing done under it.
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <variant>
#include <vector>

#include <nlohmann/json.hpp>

#include "broker/log_sink.h"
#include "service/job_queue.h"
#include "service/job_store.h"
#include "service/submission.h"

namespace rayfarm {

// One frame of a job, as the broker renders it.
struct FrameWork {
  uint64_t job = 0;
  uint32_t frame = 0;  // 0-based
  uint32_t frames = 1;
  SceneFile scene;
  RenderSettings settings;
  std::vector<RowBand> restored;  // rows journaled before a restart, not to render again
};

// A request the API answers with 404 / 409 rather than 400.
struct NotFound : std::runtime_error {
  using std::runtime_error::runtime_error;
};
struct NotReady : std::runtime_error {
  using std::runtime_error::runtime_error;
};
// ... and with 422: an Idempotency-Key already used for another request body.
struct KeyReused : std::runtime_error {
  using std::runtime_error::runtime_error;
};
// ... and with 500: a file of the state folder could not be read.
struct StateFault : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// A submission's Idempotency-Key (docs/api.md) and the hash of the request
// body it came with; an empty key makes every submission a new job.
struct SubmissionKey {
  std::string key;
  std::string body_hash;  // 16 hex digits
};

// What a keyed submission made: a new job, or the one an earlier submission
// with the same key and body made (its answer lost, the request sent again).
struct Submitted {
  uint64_t id = 0;
  bool earlier = false;
};

class JobService {
 public:
  // Opens (or creates) the state folder and restores its jobs. A job whose
  // files are damaged or disagree is set aside (JobStore::set_aside) with a
  // line to `log` ({} = stderr): "DIR/jobs/ID: cannot restore the job: ...";
  // a journal whose torn or corrupt tail was dropped gets a line too.
  // A submitted frame's float image must fit in max_image_bytes (the broker's limit).
  // A folder locked by another broker is waited for until `stop` (if given)
  // is true: LockWaitStopped (service/folder_lock.h).
  explicit JobService(const std::string& state_dir, uint64_t max_image_bytes = UINT64_MAX,
                      const LogSink& log = {}, const std::atomic<bool>* stop = nullptr);

  // ---- API side -------------------------------------------------------------
  // Checks and stores a submission; returns the new job's id. InputError for bad input.
  uint64_t submit(const nlohmann::json& body);
  // The same, or the job an earlier submission with `key` made, kept across
  // restarts. KeyReused if that came with another body; a submission with the
  // key still being stored is waited for.
  Submitted submit(const nlohmann::json& body, const SubmissionKey& key);
  nlohmann::json status(uint64_t id) const;  // NotFound
  nlohmann::json list() const;
  // Cancels a queued or running job. Returns its status; NotReady if it had finished.
  nlohmann::json cancel(uint64_t id);
  // A finished frame (frame_file.h bytes); NotReady until it is.
  std::string frame(uint64_t id, uint32_t frame) const;
  nlohmann::json record(uint64_t id, uint32_t frame) const;

  // ---- broker side ----------------------------------------------------------
  // The frame to render now (its job starts if it was queued), or nothing.
  std::optional<FrameWork> next_frame();
  // The frame that will follow `current` (same job or the next queued one),
  // without starting anything: for announcing it while `current` finishes.
  std::optional<FrameWork> frame_after(const FrameWork& current) const;
  // Journals first, then counts: a row is done once it is in the folder.
  void rows_sent(const FrameWork& f, int y0, int y1);
  void rows_accepted(const FrameWork& f, RowBand band);
  void frame_finished(const FrameWork& f, const std::vector<float>& rgb, const nlohmann::json& record);
  void fail(uint64_t id, const std::string& reason);
  // False once the job was cancelled (or failed).
  bool is_running(uint64_t id) const;
  // What a stop leaves for the next start, for the service's last log line:
  // "job 3 frame 2/5 resumes with 212 of 480 rows journaled; 4 job(s) queued".
  std::string left_to_resume() const;

  const std::string& state_dir() const { return store_.dir(); }
  JobStore& store() { return store_; }

 private:
  struct Job {
    // While the job is unfinished: a finished job's scenes are not needed again
    // (its frames and records are files), and held for every job they would
    // fill the memory of a long-running service. Dropped when it finishes, and
    // never read at start for a job found finished (StoredJob::submission).
    Submission submission;
    std::vector<RenderSettings> frames;
    std::vector<RowBand> restored;  // of the current frame
    std::string hash;               // of its scenes and settings, for its journal's owner
    std::string first_scene;        // for the list; "" if its stored submission gives none
    // Its scenes' names, for status(); a job found finished at start has them
    // read from its submission.json when first asked for.
    mutable std::optional<std::vector<std::string>> names;
    mutable bool unreadable_said = false;  // its submission.json's fault is logged once
  };
  // What the job's rows journal of `frame` (0-based) belongs to: "submission HASH frame N".
  std::string journal_owner(uint64_t id, uint32_t frame) const;
  // A restored journal that names another owner: set aside (or removed, when
  // it is this job's own of a finished frame), its rows not used.
  void check_journal_owner(StoredJob& stored, const Job& j);
  FrameWork frame_work(uint64_t id, uint32_t frame) const;
  void restore(StoredJob stored);
  // Drops a job's scenes and settings once it has finished (Job::submission).
  void release(uint64_t id);
  // A finished job's scene names from its submission.json, read outside the
  // lock (a large submission must not stall the broker loop), or why they
  // cannot be: the job is still served without them.
  std::variant<std::vector<std::string>, std::string> stored_names(uint64_t id, int frames) const;
  const Job& job(uint64_t id) const;
  // The job a submission with `key` made, once it is stored; nothing if none did.
  std::optional<uint64_t> earlier_job(std::unique_lock<std::mutex>& lock, const SubmissionKey& key);
  bool still_running(uint64_t id) const;
  // Saves the job's status as the queue now has it, or puts `before` back and rethrows (StateFault).
  void save_or_put_back(const JobStatus& before);
  // The folder's marker removed while the service runs is written back, with
  // a log line, at the next submission or frame (JobStore::restore_marker).
  void keep_marker();

  mutable std::mutex mutex_;
  const uint64_t max_image_bytes_;
  const LogSink log_;
  bool marker_unwritable_ = false;  // said once, not at every frame
  JobStore store_;
  JobQueue queue_;
  std::map<uint64_t, Job> jobs_;
  // Idempotency-Keys of the jobs (one each at most, bounded in length), and
  // of submissions still being stored: those are in keys_ and not yet in jobs_.
  std::map<std::string, uint64_t> keys_;
  std::condition_variable key_stored_;
  uint64_t next_id_ = 1, next_order_ = 1;
};

}  // namespace rayfarm
