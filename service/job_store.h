// JobStore: the service's state folder, the only place the broker's memory is
// kept across a crash. Layout (format version 1, docs/deployment.md):
//
//   DIR/rayfarm-state.json          {"format": "rayfarm-state", "version": 1}
//   DIR/last-id                     the highest id given to a job, its folder removed or not
//   DIR/jobs/ID/submission.json     what was submitted (written once)
//   DIR/jobs/ID/status.json         state and counters (rewritten on each change),
//                                   and the Idempotency-Key it was submitted with
//   DIR/jobs/ID/rows.journal        accepted rows of unfinished frames (journal.h)
//   DIR/jobs/ID/frame-0001.rgbf     finished frames, float RGB (image_file.h)
//   DIR/jobs/ID/record-0001.json    each frame's job record (broker/job_record.h)
//   DIR/damaged/ID/                 a job folder that could not be restored, set aside whole
//
// Every whole file is written atomically (tracer/output_file.h), so a crash
// leaves the old version or the new one, never half of one. A store holds the
// folder locked while it lives (service/folder_lock.h).
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <variant>
#include <vector>

#include <nlohmann/json.hpp>

#include "service/folder_lock.h"
#include "service/job_queue.h"
#include "service/journal.h"
#include "tracer/ray_stats.h"

namespace rayfarm {

inline constexpr int kStateVersion = 1;

// Rows of one frame, as journaled when the broker accepted them.
struct RowBand {
  uint32_t frame = 0;  // 0-based
  int y0 = 0, y1 = 0, width = 0;
  RayStats stats;
  std::vector<float> rgb;  // (y1 - y0) * width * 3
};

// Rows handed to a worker: journaled too, so that after a crash the rows that
// were in flight (and are rendered again) can be counted.
struct RowsSent {
  uint32_t frame = 0;
  int y0 = 0, y1 = 0;
};

std::string encode_journal_record(const RowBand& band);
std::string encode_journal_record(const RowsSent& sent);
// A rows journal's first record names what its rows belong to, e.g.
// "submission 0123456789abcdef frame 2" (JobService): a journal copied from
// another job, or one whose job's submission.json was edited since, is told
// apart by it rather than have its rows mixed into this job's image. Journals
// written before it existed have none and are read as before.
std::string encode_journal_owner(const std::string& owner);
// Throws InputError for a record that is neither (a journal from another
// format would be caught by the version in its header first).
std::variant<RowBand, RowsSent> decode_journal_record(const std::string& record);

// A job as found in the state folder.
struct StoredJob {
  JobStatus status;
  // An unfinished job's, read whole. A finished (done, failed, cancelled)
  // job's is not read at start: the API serves it from its status, frames
  // and records, and thousands of them would make every start slow and keep
  // their scenes in memory for good. Only its first scene's name is read
  // (for the job list), "" if the file does not give one.
  nlohmann::json submission;
  std::string first_scene;
  std::vector<RowBand> rows;   // journaled rows of unfinished frames
  std::vector<RowsSent> sent;  // journaled hand-outs of unfinished frames
  JournalRecovery journal;    // what opening the journal found (records moved to `rows`)
  std::string journal_owner;  // its first record's (encode_journal_owner); empty in an older journal
  // A finished job's journal, left by a stop between its status and the
  // journal's removal (a cancel, a last frame): removed at load. What came
  // of it, "removed" or "cannot be removed (...)"; empty if there was none.
  std::string leftover_journal;
  // Records whole by their checksum that do not decode as rows (written by
  // something else, or edited): skipped, the records around them kept.
  uint64_t unreadable_records = 0;
  std::string unreadable_reason;  // the first: "record 3 at byte 4096: journal record of unknown type"
};

// A job folder moved out of DIR/jobs because it could not be restored.
struct SetAside {
  std::string folder;    // DIR/jobs/ID
  std::string moved_to;  // DIR/damaged/ID
  std::string reason;    // e.g. "status.json: invalid JSON: ..."
};

// A job folder the broker stopped writing before the job's status: no job
// was answered for it, and it is removed at the next start.
struct Incomplete {
  std::string folder;  // DIR/jobs/ID
  std::string held;    // "nothing", "only its submission"
  std::string error;   // why it could not be removed, "" once it is
};

// A hidden temporary of an atomic write (tracer/output_file.h) that a broker
// stopped before it could rename or remove it: removed at the next start.
struct LeftTemporary {
  std::string path;   // DIR/jobs/ID/.frame-0001.rgbf.4242-7.tmp.rgbf
  std::string of;     // the file it was to become: frame-0001.rgbf
  std::string error;  // why it could not be removed, "" once it is
};

nlohmann::json status_json(const JobStatus& s);
JobStatus parse_status(const nlohmann::json& j, const std::string& where);

class JobStore {
 public:
  // Creates DIR (and its version file) or checks an existing one: InputError
  // "DIR: state format version 2; this rayfarm reads version 1", or "DIR: in
  // use by another running broker ..." while another store holds the folder.
  // A folder without rayfarm-state.json that already holds jobs/ entries,
  // last-id or damaged/ is refused, not taken over: "DIR/rayfarm-state.json:
  // missing, though DIR holds jobs/ (3 entries), last-id: ...". A lock held
  // is waited for up to `lock_wait` (folder_lock.h), said to `log` ({} = silent),
  // and no longer once `stop` (if given) is true: LockWaitStopped.
  explicit JobStore(std::string dir, const std::function<void(const std::string&)>& log = {},
                    std::chrono::milliseconds lock_wait = kFolderLockWait, const std::atomic<bool>* stop = nullptr);
  ~JobStore();

  const std::string& dir() const { return dir_; }

  // Every job in the folder, unfinished ones with their journaled rows; torn
  // journal tails are cut off here. A job folder that cannot be read is set
  // aside (see set_aside) and listed in `damaged` instead; one without its
  // status and with nothing beside its submission is removed and listed in
  // `incomplete`.
  std::vector<StoredJob> load(std::vector<SetAside>& damaged, std::vector<Incomplete>& incomplete);
  // Removes the temporaries of atomic writes left in DIR and DIR/jobs/ID/ by a
  // broker that was killed mid-write (a frame's is as large as the frame) and
  // lists them. The folder is locked: no running broker is writing them.
  std::vector<LeftTemporary> remove_temporaries();
  // Moves DIR/jobs/ID whole to DIR/damaged/ID, where the operator can inspect
  // it: one damaged job must not keep the service from serving the others.
  // InputError naming both folders if it cannot be moved.
  SetAside set_aside(uint64_t id, const std::string& reason);
  // Above every id in DIR/last-id and DIR/damaged: ids are never reused, also
  // once a job's folder was removed or set aside.
  uint64_t next_id() const;

  // Safe to call from several threads at once (the API's submissions).
  void create(const JobStatus& status, const nlohmann::json& submission);
  void save_status(const JobStatus& status);
  nlohmann::json read_submission(uint64_t id) const;
  // The names of the job's scenes from its submission.json, its scene text
  // not kept (submission.h, scene_names_in). InputError naming the file if it
  // is missing, not a regular file, or cannot be read as a submission.
  std::vector<std::string> scene_names(uint64_t id, bool first_only = false) const;

  // Appends to the job's journal (opened on first use, `owner` its first record).
  template <class Record> void journal(uint64_t id, const std::string& owner, const Record& r) {
    journal_of(id, owner).append(encode_journal_record(r));
  }
  // Moves the job's journal aside in its folder (rows.journal.foreign, -2, ...)
  // and returns where it went: it belongs to something else, its rows must not
  // be used, yet they are the operator's to inspect. InputError if it cannot move.
  std::string set_journal_aside(uint64_t id);
  // The job is finished: its journal is no longer needed (the frames are written).
  void close_journal(uint64_t id, bool remove);
  std::string journal_path(uint64_t id) const;
  uint64_t journal_bytes(uint64_t id) const;

  void write_frame(uint64_t id, uint32_t frame, int width, int height, const std::vector<float>& rgb);
  std::string frame_path(uint64_t id, uint32_t frame) const;
  void write_record(uint64_t id, uint32_t frame, const nlohmann::json& record);
  std::string record_path(uint64_t id, uint32_t frame) const;

  // Writes DIR/rayfarm-state.json back if it was removed while this store
  // holds the folder, and returns whether it did. Noticed only at the next
  // start, that start would refuse the folder (a marker missing beside jobs).
  // The folder is this store's own (locked, its marker checked or written at
  // start): nothing is taken over. InputError if it cannot be written.
  bool restore_marker();

  // A file written elsewhere that should appear in the folder, e.g. the
  // bound HTTP address for scripts and tests. A symbolic link in its place is
  // replaced, not written through.
  void write_note(const std::string& name, const std::string& text);

 private:
  std::string job_dir(uint64_t id) const;
  std::string marker_path() const { return dir_ + "/rayfarm-state.json"; }
  StoredJob load_job(const std::string& folder);
  Incomplete remove_incomplete(const std::string& folder);
  SetAside move_aside(const std::string& folder, std::string reason);
  Journal& journal_of(uint64_t id, const std::string& owner);
  std::string dir_;
  std::optional<FolderLock> lock_;  // taken once the folder exists
  std::mutex last_id_mutex_;         // creates run in parallel; DIR/last-id only grows
  uint64_t last_id_ = 0;
  std::map<uint64_t, std::unique_ptr<Journal>> journals_;
};

}  // namespace rayfarm
