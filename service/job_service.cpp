// The service's jobs; see job_service.h.
#include "service/job_service.h"

#include <algorithm>
#include <cstdio>
#include <filesystem>

#include "protocol/codec.h"
#include "tracer/error.h"
#include "tracer/text_file.h"

namespace rayfarm {

using nlohmann::json;

namespace {

int64_t rows_of(const std::vector<RenderSettings>& frames, size_t first, size_t last) {
  int64_t rows = 0;
  for (size_t i = first; i < last; ++i) rows += frames[i].height;
  return rows;
}

// Keeps the first journaled band for each row: a band overlapping rows already
// restored cannot come from one broker run, and the first copy is as good.
std::vector<RowBand> distinct_rows(std::vector<RowBand> bands, const RenderSettings& s) {
  std::vector<bool> have(static_cast<size_t>(s.height), false);
  std::vector<RowBand> out;
  for (RowBand& b : bands) {
    if (b.width != s.width || b.y1 > s.height) continue;
    if (std::any_of(have.begin() + b.y0, have.begin() + b.y1, [](bool h) { return h; })) continue;
    std::fill(have.begin() + b.y0, have.begin() + b.y1, true);
    out.push_back(std::move(b));
  }
  return out;
}

// The hash of what makes a job's image: its scenes and settings, not its
// priority (which may change, the pixels not).
std::string submission_hash(Submission s) {
  s.priority = 0;
  return protocol::hash_hex(protocol::fnv1a64(submission_json(s).dump()));
}

// Rows of `frame` handed out (journaled as sent) and not journaled as done:
// in flight at the crash, they are rendered again. Each row once: one handed
// out twice (a backup copy of a straggler, a lost task handed out again) is
// rendered once more, not twice.
int rows_in_flight(const std::vector<RowsSent>& sent, const std::vector<RowBand>& restored, uint32_t frame,
                   int height) {
  std::vector<bool> flying(static_cast<size_t>(height), false);
  for (const RowsSent& s : sent)
    if (s.frame == frame && s.y0 >= 0 && s.y0 <= s.y1 && s.y1 <= height)
      std::fill(flying.begin() + s.y0, flying.begin() + s.y1, true);
  for (const RowBand& b : restored) std::fill(flying.begin() + b.y0, flying.begin() + b.y1, false);
  return static_cast<int>(std::count(flying.begin(), flying.end(), true));
}

std::vector<std::string> names_of(const Submission& s) {
  std::vector<std::string> names;
  for (const SceneFile& f : s.scenes) names.push_back(f.name);
  return names;
}

std::string owner_text(const std::string& hash, uint32_t frame) {
  return "submission " + hash + " frame " + std::to_string(frame + 1);
}

}  // namespace

JobService::JobService(const std::string& state_dir, uint64_t max_image_bytes,
                       const LogSink& log, const std::atomic<bool>* stop)
    : max_image_bytes_(max_image_bytes),
      log_(log),
      store_(state_dir, [this](const std::string& line) { write_log(log_, line); }, kFolderLockWait, stop) {
  const auto say = [&](const std::string& line) { write_log(log_, line); };
  for (const LeftTemporary& t : store_.remove_temporaries())
    say(t.path + ": left by a broker that stopped while writing " + t.of + "; " +
        (t.error.empty() ? "removed" : "cannot remove it (" + t.error + "), left in place"));
  std::vector<SetAside> damaged;
  std::vector<Incomplete> incomplete;
  std::vector<StoredJob> stored = store_.load(damaged, incomplete);
  for (const Incomplete& f : incomplete)
    say(f.folder + ": a job folder holding " + f.held + ", without status.json: the broker stopped while " +
        "creating the job, before answering its submission; " +
        (f.error.empty() ? "removed" : "cannot remove it (" + f.error + "), left in place"));
  for (StoredJob& s : stored) {
    const uint64_t id = s.status.id;
    if (!s.leftover_journal.empty())
      say(store_.journal_path(id) + ": left behind by the " + job_state_name(s.status.state) +
          " job (a stop between its status and the journal's removal); " + s.leftover_journal);
    if (s.journal.dropped_bytes > 0)
      say(store_.journal_path(id) + ": dropped " + std::to_string(s.journal.dropped_bytes) +
          " byte(s) at its end, torn or corrupt (" + s.journal.dropped_reason +
          "); any rows in them are rendered again");
    if (s.unreadable_records > 0)
      say(store_.journal_path(id) + ": skipped " + std::to_string(s.unreadable_records) +
          " record(s) whole by their checksum that cannot be read as rows (" + s.unreadable_reason +
          "); the rows in them are rendered again, the other " + std::to_string(s.rows.size() + s.sent.size()) +
          " record(s) kept");
    try {
      restore(std::move(s));
    } catch (const std::exception& e) {
      damaged.push_back(store_.set_aside(id, e.what()));
    }
  }
  for (const SetAside& d : damaged)
    say(d.folder + ": cannot restore the job: " + d.reason + "; moved whole to " + d.moved_to +
        ", the other jobs go on");
  next_id_ = std::max(next_id_, store_.next_id());
}

namespace {

// A file of the state folder that cannot be read (removed, damaged) or written
// (a full disk, a read-only folder) is the service's fault, not the client's
// nor the job's: the API answers 500, where the file's InputError would say
// 400, "bad input", and the broker loop stops with the job's rows journaled,
// where an InputError would fail the job and drop them.
template <class Access> auto state_file(Access access) {
  try {
    return access();
  } catch (const InputError& e) {
    throw StateFault(std::string("the state folder: ") + e.what());
  } catch (const JournalError& e) {  // a full disk under the journal, as under a frame
    throw StateFault(std::string("the state folder: ") + e.what());
  }
}

}  // namespace

// A job found in the state folder: an unfinished one has its frames derived
// again from the submission (the same rule that accepted it), and its current
// frame gets the rows its journal holds. A finished one is served from its
// status and files alone (StoredJob::submission).
void JobService::restore(StoredJob stored) {
  JobStatus& st = stored.status;
  Job j;
  next_order_ = std::max(next_order_, st.order + 1);
  next_id_ = std::max(next_id_, st.id + 1);
  if (is_finished(st.state)) {
    j.first_scene = std::move(stored.first_scene);
    queue_.add(st);
    jobs_[st.id] = std::move(j);
    if (!st.idempotency_key.empty()) keys_.emplace(st.idempotency_key, st.id);
    return;
  }
  try {
    j.submission = parse_submission(stored.submission);
    j.frames = check_submission(j.submission);
  } catch (const InputError& e) {
    throw InputError(std::string("submission.json: ") + e.what());
  }
  j.hash = submission_hash(j.submission);
  if (static_cast<size_t>(st.frames) != j.frames.size() || st.frames_done >= st.frames)
    throw InputError("status.json counts " + std::to_string(st.frames_done) + " of " + std::to_string(st.frames) +
                     " frame(s) done, state " + job_state_name(st.state) + "; submission.json has " +
                     std::to_string(j.frames.size()) + " frame(s)");
  check_journal_owner(stored, j);
  const uint32_t current = static_cast<uint32_t>(st.frames_done);
  std::vector<RowBand> bands;
  for (RowBand& b : stored.rows)
    if (b.frame == current) bands.push_back(std::move(b));
  j.restored = distinct_rows(std::move(bands), j.frames.at(current));
  int restored_rows = 0;
  for (const RowBand& b : j.restored) restored_rows += b.y1 - b.y0;
  st.rows_done = rows_of(j.frames, 0, current) + restored_rows;
  st.resumed_rows += restored_rows;
  st.rerendered_rows += rows_in_flight(stored.sent, j.restored, current, j.frames.at(current).height);
  j.first_scene = j.submission.scenes.front().name;
  j.names = names_of(j.submission);
  queue_.add(st);
  jobs_[st.id] = std::move(j);
  if (!st.idempotency_key.empty()) keys_.emplace(st.idempotency_key, st.id);
}

void JobService::release(uint64_t id) {
  Job& j = jobs_.at(id);
  j.submission = Submission{};
  std::vector<RenderSettings>().swap(j.frames);
  std::vector<RowBand>().swap(j.restored);
}

void JobService::check_journal_owner(StoredJob& stored, const Job& j) {
  const uint64_t id = stored.status.id;
  const uint32_t current = static_cast<uint32_t>(stored.status.frames_done);
  const std::string expected = owner_text(j.hash, current);
  if (stored.journal_owner.empty() || stored.journal_owner == expected) return;  // older journals name none
  stored.rows.clear();
  stored.sent.clear();
  // This job's own journal of a frame already saved as done: a stop came
  // between the frame and the journal's removal. Its rows are not needed.
  for (uint32_t done = 0; done < current; ++done)
    if (stored.journal_owner == owner_text(j.hash, done)) {
      store_.close_journal(id, true);
      write_log(log_, store_.journal_path(id) + ": holds rows of frame " + std::to_string(done + 1) +
                          ", already saved as done; removed");
      return;
    }
  const std::string moved_to = store_.set_journal_aside(id);
  write_log(log_, store_.journal_path(id) + ": belongs to " + stored.journal_owner + ", not to this job (" +
                      expected + ": submission.json edited, or the journal copied from another job); moved aside to " +
                      moved_to + ", its rows not used: the frame is rendered from the start");
}

std::string JobService::journal_owner(uint64_t id, uint32_t frame) const {
  return owner_text(jobs_.at(id).hash, frame);
}

const JobService::Job& JobService::job(uint64_t id) const {
  auto it = jobs_.find(id);
  if (it == jobs_.end()) throw NotFound("no job " + std::to_string(id));
  return it->second;
}

uint64_t JobService::submit(const json& body) { return submit(body, SubmissionKey{}).id; }

Submitted JobService::submit(const json& body, const SubmissionKey& key) {
  {
    // A request sent again is answered before its scenes are parsed again.
    std::unique_lock<std::mutex> lock(mutex_);
    if (const auto earlier = earlier_job(lock, key)) return {*earlier, true};
  }
  Job j;
  j.submission = parse_submission(body);
  check_scene_names(j.submission);  // here, not in restore(): a job stored with such a name is still served
  j.frames = check_submission(j.submission, max_image_bytes_);  // parses every scene: outside the lock
  j.hash = submission_hash(j.submission);
  j.first_scene = j.submission.scenes.front().name;
  j.names = names_of(j.submission);
  JobStatus st;
  st.priority = j.submission.priority;
  st.frames = static_cast<int>(j.frames.size());
  st.rows_total = rows_of(j.frames, 0, j.frames.size());
  st.idempotency_key = key.key;
  st.body_hash = key.key.empty() ? "" : key.body_hash;
  {
    std::unique_lock<std::mutex> lock(mutex_);
    if (const auto earlier = earlier_job(lock, key)) return {*earlier, true};  // sent twice at once
    st.id = next_id_++;
    st.order = next_order_++;
    if (!key.key.empty()) keys_[key.key] = st.id;  // a second request with it waits for this one
  }
  // Written before the queue knows the job, and without the lock: a large
  // scene must not stall the broker loop's journal writes.
  try {
    state_file([&] { store_.create(st, submission_json(j.submission)); });
  } catch (...) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!key.key.empty()) keys_.erase(key.key);  // no job holds it: one sent again is a new job
    key_stored_.notify_all();
    throw;
  }
  std::lock_guard<std::mutex> lock(mutex_);
  keep_marker();
  queue_.add(st);
  jobs_[st.id] = std::move(j);
  key_stored_.notify_all();
  return {st.id, false};
}

// A client that gave up waiting for its answer sends the request again while
// the first may still be storing its job: waited for, rather than answered
// with a second job or with an id no status knows yet.
std::optional<uint64_t> JobService::earlier_job(std::unique_lock<std::mutex>& lock, const SubmissionKey& key) {
  if (key.key.empty()) return std::nullopt;
  key_stored_.wait(lock, [&] {
    const auto it = keys_.find(key.key);
    return it == keys_.end() || jobs_.count(it->second) > 0;
  });
  const auto it = keys_.find(key.key);
  if (it == keys_.end()) return std::nullopt;
  const JobStatus& s = queue_.get(it->second);
  if (s.body_hash != key.body_hash)
    throw KeyReused("Idempotency-Key '" + key.key + "': already used by job " + std::to_string(it->second) +
                    " for another request body; a key names one submission (send a new key for a new job)");
  return it->second;
}

json JobService::status(uint64_t id) const {
  std::unique_lock<std::mutex> lock(mutex_);
  const Job& j = job(id);
  json s = status_json(queue_.get(id));
  if (!j.names) {  // a job found finished at start: read once, outside the lock (stored_names)
    lock.unlock();
    auto read = stored_names(id, s.at("frames").get<int>());
    lock.lock();  // the job stays: none is removed while the service runs
    if (auto* error = std::get_if<std::string>(&read)) {
      s["submission_error"] = *error;
      if (!j.unreadable_said)
        write_log(log_, *error + "; job " + std::to_string(id) + " (" + s.at("state").get<std::string>() +
                            ") is still served, its status, frames and records, without its scene names");
      j.unreadable_said = true;
      return s;
    }
    if (!j.names) j.names = std::move(std::get<std::vector<std::string>>(read));
  }
  s["scenes"] = *j.names;
  return s;
}

std::variant<std::vector<std::string>, std::string> JobService::stored_names(uint64_t id, int frames) const {
  try {
    std::vector<std::string> names = store_.scene_names(id);
    if (names.size() != static_cast<size_t>(frames))
      return store_.dir() + "/jobs/" + std::to_string(id) + "/submission.json: holds " + std::to_string(names.size()) +
             " scene(s), status.json counts " + std::to_string(frames) + " frame(s)";
    return names;
  } catch (const InputError& e) {
    return std::string(e.what());
  }
}

json JobService::list() const {
  std::lock_guard<std::mutex> lock(mutex_);
  json out = json::array();
  for (const JobStatus& s : queue_.list()) {
    out.push_back(status_json(s));
    const std::string& first = jobs_.at(s.id).first_scene;  // the first: a list stays small for any frame count
    if (!first.empty()) out.back()["scene"] = first;
  }
  return out;
}

json JobService::cancel(uint64_t id) {
  std::lock_guard<std::mutex> lock(mutex_);
  job(id);
  const JobStatus before = queue_.get(id);
  if (!queue_.cancel(id))
    throw NotReady("job " + std::to_string(id) + " is already " + job_state_name(before.state));
  // Cancelled in memory only, the job would be answered as cancelled yet run
  // again after a restart. It goes on as before; the 500 says the cancel did not happen.
  save_or_put_back(before);
  store_.close_journal(id, true);
  release(id);
  return status_json(queue_.get(id));
}

namespace {

// A frame past the job's last is not there (404), for its image and its
// record alike: answered "not yet" (409), a client waiting for it waited forever.
void check_frame_number(uint64_t id, const JobStatus& s, uint32_t frame) {
  if (frame >= static_cast<uint32_t>(s.frames))
    throw NotFound("job " + std::to_string(id) + " has " + std::to_string(s.frames) + " frame(s)");
}

// Why a frame of the job has nothing to give (409): "yet" while the job may
// still render it; of a cancelled or failed job, "yet" sent a client back to
// wait for a frame that never comes.
std::string not_rendered(const JobStatus& s, const std::string& what) {
  const std::string state = job_state_name(s.state);
  return is_finished(s.state) ? what + ": the job is " + state + " and will not render it"
                              : what + " yet (" + state + ")";
}

}  // namespace

std::string JobService::frame(uint64_t id, uint32_t frame) const {
  std::lock_guard<std::mutex> lock(mutex_);
  job(id);
  const JobStatus& s = queue_.get(id);
  check_frame_number(id, s, frame);
  if (static_cast<int>(frame) >= s.frames_done)
    throw NotReady(not_rendered(s, "job " + std::to_string(id) + " frame " + std::to_string(frame + 1) +
                                           " is not rendered"));
  return state_file([&] { return read_text_file(store_.frame_path(id, frame)); });
}

json JobService::record(uint64_t id, uint32_t frame) const {
  std::lock_guard<std::mutex> lock(mutex_);
  job(id);
  const JobStatus& s = queue_.get(id);
  check_frame_number(id, s, frame);
  if (!std::filesystem::exists(store_.record_path(id, frame)))
    throw NotReady(
        not_rendered(s, "job " + std::to_string(id) + " has no record for frame " + std::to_string(frame + 1)));
  return state_file([&] { return read_json_file(store_.record_path(id, frame)); });
}

FrameWork JobService::frame_work(uint64_t id, uint32_t frame) const {
  const Job& j = jobs_.at(id);
  FrameWork f;
  f.job = id;
  f.frame = frame;
  f.frames = static_cast<uint32_t>(j.frames.size());
  f.scene = j.submission.scenes[frame];
  f.settings = j.frames[frame];
  if (frame == static_cast<uint32_t>(queue_.get(id).frames_done)) f.restored = j.restored;
  return f;
}

std::optional<FrameWork> JobService::next_frame() {
  std::lock_guard<std::mutex> lock(mutex_);
  const auto id = queue_.next();
  if (!id) return std::nullopt;
  keep_marker();
  if (queue_.get(*id).state == JobState::queued) {
    const JobStatus before = queue_.get(*id);
    queue_.start(*id);
    save_or_put_back(before);
  }
  return frame_work(*id, static_cast<uint32_t>(queue_.get(*id).frames_done));
}

std::optional<FrameWork> JobService::frame_after(const FrameWork& current) const {
  std::lock_guard<std::mutex> lock(mutex_);
  if (current.frame + 1 < current.frames && queue_.get(current.job).state == JobState::running)
    return frame_work(current.job, current.frame + 1);
  const auto id = queue_.after(current.job);
  if (!id) return std::nullopt;
  return frame_work(*id, 0);
}

// All or nothing: a change the folder did not take is undone in memory too,
// so that what the API answers is what a restart finds (and a later call
// tries the change again rather than find it made).
void JobService::save_or_put_back(const JobStatus& before) {
  try {
    state_file([&] { store_.save_status(queue_.get(before.id)); });
  } catch (...) {
    queue_.put_back(before);
    throw;
  }
}

// Without its marker the folder is refused at the next start, jobs and all:
// an operator should hear of it now, while the service can still put it back,
// not after a restart weeks later. A folder that takes no writes stops no
// job here; the next write that matters says so.
void JobService::keep_marker() {
  try {
    if (store_.restore_marker())
      write_log(log_, store_.dir() + "/rayfarm-state.json: removed while the service ran; written back (without it "
                                     "the next start would refuse the folder)");
    marker_unwritable_ = false;
  } catch (const InputError& e) {
    if (!marker_unwritable_)
      write_log(log_, std::string(e.what()) + ": the folder's marker was removed while the service ran and cannot "
                                              "be written back; the next start will refuse the folder until it is");
    marker_unwritable_ = true;
  }
}

// A cancelled job's journal is gone; nothing more is written for it.
bool JobService::still_running(uint64_t id) const { return queue_.get(id).state == JobState::running; }

void JobService::rows_sent(const FrameWork& f, int y0, int y1) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (still_running(f.job))
    state_file([&] { store_.journal(f.job, journal_owner(f.job, f.frame), RowsSent{f.frame, y0, y1}); });
}

void JobService::rows_accepted(const FrameWork& f, RowBand band) {
  band.frame = f.frame;
  const int rows = band.y1 - band.y0;
  std::lock_guard<std::mutex> lock(mutex_);
  if (!still_running(f.job)) return;
  // A journal that cannot be opened or written (a full disk) stops the service, as a frame that cannot be saved.
  state_file([&] { store_.journal(f.job, journal_owner(f.job, f.frame), band); });
  queue_.add_rows(f.job, rows);
}

void JobService::frame_finished(const FrameWork& f, const std::vector<float>& rgb, const json& record) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (!still_running(f.job)) return;
  state_file([&] {
    store_.write_frame(f.job, f.frame, f.settings.width, f.settings.height, rgb);
    store_.write_record(f.job, f.frame, record);
  });
  const JobStatus before = queue_.get(f.job);
  queue_.add_rerendered(f.job, record.value("rows_reissued", 0));
  // Whole frames are the authority: rows counted band by band catch up here.
  queue_.add_rows(f.job, rows_of(jobs_.at(f.job).frames, 0, f.frame + 1) - before.rows_done);
  queue_.frame_done(f.job);
  save_or_put_back(before);  // unsaved, the frame is still the current one, its journaled rows restored
  jobs_.at(f.job).restored.clear();
  if (!still_running(f.job)) release(f.job);
  // The journal holds the current frame only; a crash before this line leaves
  // rows of a finished frame, which restore() ignores.
  store_.close_journal(f.job, true);
}

void JobService::fail(uint64_t id, const std::string& reason) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (!still_running(id)) return;
  const JobStatus before = queue_.get(id);
  queue_.fail(id, reason);
  save_or_put_back(before);
  store_.close_journal(id, true);
  release(id);
}

bool JobService::is_running(uint64_t id) const {
  std::lock_guard<std::mutex> lock(mutex_);
  return queue_.contains(id) && still_running(id);
}

// The journal holds the current frame's rows only: the job's rows_done past
// its finished frames are those a start restores.
std::string JobService::left_to_resume() const {
  std::lock_guard<std::mutex> lock(mutex_);
  int queued = 0;
  for (const JobStatus& s : queue_.list()) queued += s.state == JobState::queued;
  const std::string waiting = queued ? std::to_string(queued) + " job(s) queued" : "no job queued";
  const auto id = queue_.next();
  if (!id || queue_.get(*id).state != JobState::running) return "no job running, " + waiting;
  const JobStatus& s = queue_.get(*id);
  const std::vector<RenderSettings>& frames = jobs_.at(*id).frames;
  const size_t current = static_cast<size_t>(s.frames_done);
  const int64_t journaled = s.rows_done - rows_of(frames, 0, current);
  return "job " + std::to_string(*id) + " frame " + std::to_string(current + 1) + "/" + std::to_string(s.frames) +
         " resumes with " + std::to_string(journaled) + " of " + std::to_string(frames.at(current).height) +
         " rows journaled; " + waiting;
}

}  // namespace rayfarm
