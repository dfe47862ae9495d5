// The state folder; see job_store.h.
#include "service/job_store.h"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <regex>
#include <stdexcept>

#include "protocol/json_fields.h"
#include "service/frame_file.h"
#include "service/submission.h"
#include "tracer/error.h"
#include "tracer/text_file.h"

namespace rayfarm {
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

constexpr char kRowTag[4] = {'R', 'O', 'W', 'S'};
constexpr char kSentTag[4] = {'S', 'E', 'N', 'T'};
constexpr char kOwnerTag[4] = {'O', 'W', 'N', 'R'};
constexpr size_t kRowHeader = 4 + 4 * 4 + 5 * 8;

template <class T> void put(std::string& out, T v) { out.append(reinterpret_cast<const char*>(&v), sizeof v); }
template <class T> T get(const std::string& in, size_t& at) {
  T v;
  std::memcpy(&v, in.data() + at, sizeof v);
  at += sizeof v;
  return v;
}

std::string numbered(const char* stem, uint32_t frame, const char* ext) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%s-%04u.%s", stem, frame + 1, ext);
  return buf;
}

// The names in a job folder besides submission.json and the hidden
// temporaries of atomic writes, "a, b, c and 97 more"; empty if there are none.
std::string files_beside_submission(const std::string& folder) {
  std::vector<std::string> names;
  for (const auto& entry : fs::directory_iterator(folder)) {
    std::string name = entry.path().filename().string();
    if (name != "submission.json" && name.front() != '.') names.push_back(std::move(name));
  }
  std::sort(names.begin(), names.end());
  std::string out;
  for (size_t i = 0; i < names.size() && i < 3; ++i) out += (i ? ", " : "") + names[i];
  if (names.size() > 3) out += " and " + std::to_string(names.size() - 3) + " more";
  return out;
}

// What `path` is, its symbolic link not followed: "a FIFO", "a symbolic link
// (to /tmp/x)", ... for the messages that refuse it.
std::string kind_of(const fs::path& path) {
  std::error_code ec;
  switch (fs::symlink_status(path, ec).type()) {
    case fs::file_type::regular: return "a regular file";
    case fs::file_type::directory: return "a folder";
    case fs::file_type::symlink: return "a symbolic link (to " + fs::read_symlink(path, ec).string() + ")";
    case fs::file_type::fifo: return "a FIFO";
    case fs::file_type::socket: return "a socket";
    case fs::file_type::block: return "a block device";
    case fs::file_type::character: return "a character device";
    case fs::file_type::not_found: return "missing";
    default: return "of an unknown kind";
  }
}

// The state folder's files are read whole at start: a FIFO (or a device)
// would block the service there for good, before it serves anything.
// InputError "path: a FIFO, not a regular file".
void require_regular(const fs::path& path) {
  std::error_code ec;
  if (fs::symlink_status(path, ec).type() != fs::file_type::regular)
    throw InputError(path.string() + ": " + kind_of(path) + ", not a regular file");
}

// Present in any form, a symbolic link to nowhere included (fs::exists follows it).
bool present(const fs::path& path) {
  std::error_code ec;
  return fs::exists(fs::symlink_status(path, ec));
}

// A job folder's files are each read at some point (at start, or when a frame
// is fetched): one that is not a regular file sets the job aside at start,
// rather than block the service or an API request later. Folders inside it
// are not read and stay. The first such name, sorted, is the one reported.
void require_regular_files(const std::string& folder) {
  std::vector<fs::path> odd;
  for (const auto& entry : fs::directory_iterator(folder)) {
    const fs::file_type type = entry.symlink_status().type();
    if (type != fs::file_type::regular && type != fs::file_type::directory) odd.push_back(entry.path());
  }
  if (!odd.empty()) require_regular(*std::min_element(odd.begin(), odd.end()));
}

// The names a state folder gets once it has served (besides its marker and
// service.json), "jobs/ (2 entries), last-id"; empty if there are none. An
// empty jobs/ is what a first start that died before its marker leaves.
std::string state_left_in(const std::string& dir) {
  std::vector<std::string> found;
  std::error_code ec;
  const fs::path jobs = fs::path(dir) / "jobs";
  if (fs::is_directory(fs::symlink_status(jobs, ec))) {
    const auto entries = std::distance(fs::directory_iterator(jobs, ec), fs::directory_iterator());
    if (entries > 0) found.push_back("jobs/ (" + std::to_string(entries) + (entries == 1 ? " entry)" : " entries)"));
  }
  for (const char* name : {"last-id", "damaged"})
    if (present(fs::path(dir) / name)) found.push_back(name);
  std::string out;
  for (size_t i = 0; i < found.size(); ++i) out += (i ? ", " : "") + found[i];
  return out;
}

// A folder without the marker is made a state folder only if it holds no
// state: one with job folders is another program's folder (whose jobs/ the
// start would move into damaged/ one by one), or a state folder whose marker
// was removed, which an operator should hear of rather than have it rewritten.
void require_new_state_folder(const std::string& dir, const std::string& version_file) {
  const std::string found = state_left_in(dir);
  if (found.empty()) return;
  throw InputError(version_file + ": missing, though " + dir + " holds " + found +
                   ": not a rayfarm state folder, or its marker was removed (to serve it as one, write "
                   "{\"format\": \"rayfarm-state\", \"version\": " +
                   std::to_string(kStateVersion) + "} there)");
}

// The file a temporary of an atomic write was to become: "frame-0001.rgbf"
// for ".frame-0001.rgbf.4242-7.tmp.rgbf" (tracer/output_file.cpp names them
// ".NAME.PID-N.tmp.EXT"); empty for any other name.
std::string temporary_of(const std::string& name) {
  static const std::regex temporary(R"(\.(.+)\.[0-9]+-[0-9]+\.tmp(\.[^.]*)?)");
  std::smatch m;
  if (!std::regex_match(name, m, temporary)) return "";
  const std::string target = m[1], ext = m[2];
  if (target.size() < ext.size() || target.compare(target.size() - ext.size(), ext.size(), ext) != 0) return "";
  return target;
}

}  // namespace

// Host byte order, as frame_file.h: the journal is read back by the machine that wrote it.
std::string encode_journal_record(const RowsSent& s) {
  std::string out(kSentTag, sizeof kSentTag);
  put<uint32_t>(out, s.frame);
  put<int32_t>(out, s.y0);
  put<int32_t>(out, s.y1);
  return out;
}

std::string encode_journal_record(const RowBand& b) {
  std::string out(kRowTag, sizeof kRowTag);
  put<uint32_t>(out, b.frame);
  put<int32_t>(out, b.y0);
  put<int32_t>(out, b.y1);
  put<int32_t>(out, b.width);
  for (uint64_t v : {b.stats.eye, b.stats.eye_hit, b.stats.shadow, b.stats.reflection, b.stats.refraction})
    put<uint64_t>(out, v);
  out.append(reinterpret_cast<const char*>(b.rgb.data()), b.rgb.size() * sizeof(float));
  return out;
}

std::string encode_journal_owner(const std::string& owner) { return std::string(kOwnerTag, sizeof kOwnerTag) + owner; }

std::variant<RowBand, RowsSent> decode_journal_record(const std::string& rec) {
  size_t at = sizeof kRowTag;
  if (rec.size() == 16 && std::memcmp(rec.data(), kSentTag, sizeof kSentTag) == 0) {
    RowsSent s;
    s.frame = get<uint32_t>(rec, at);
    s.y0 = get<int32_t>(rec, at);
    s.y1 = get<int32_t>(rec, at);
    return s;
  }
  if (rec.size() < kRowHeader || std::memcmp(rec.data(), kRowTag, sizeof kRowTag) != 0)
    throw InputError("journal record of unknown type");
  RowBand b;
  b.frame = get<uint32_t>(rec, at);
  b.y0 = get<int32_t>(rec, at);
  b.y1 = get<int32_t>(rec, at);
  b.width = get<int32_t>(rec, at);
  for (uint64_t* v : {&b.stats.eye, &b.stats.eye_hit, &b.stats.shadow, &b.stats.reflection, &b.stats.refraction})
    *v = get<uint64_t>(rec, at);
  if (b.y0 < 0 || b.y1 <= b.y0 || b.width < 1 ||
      rec.size() - at != size_t(b.y1 - b.y0) * size_t(b.width) * 3 * sizeof(float))
    throw InputError("journal row band " + std::to_string(b.y0) + ":" + std::to_string(b.y1) + " has the wrong size");
  b.rgb.resize((rec.size() - at) / sizeof(float));
  std::memcpy(b.rgb.data(), rec.data() + at, rec.size() - at);
  return b;
}

json status_json(const JobStatus& s) {
  json j = {{"id", s.id},
            {"state", job_state_name(s.state)},
            {"priority", s.priority},
            {"order", s.order},
            {"frames", s.frames},
            {"frames_done", s.frames_done},
            {"rows_done", s.rows_done},
            {"rows_total", s.rows_total},
            {"resumed_rows", s.resumed_rows},
            {"rerendered_rows", s.rerendered_rows}};
  if (!s.error.empty()) j["error"] = s.error;
  return j;
}

JobStatus parse_status(const json& j, const std::string& where) {
  JsonFields f(j, where);
  JobStatus s;
  constexpr int kMax = std::numeric_limits<int>::max();
  s.id = f.unsigned64("id");
  const std::string state = f.string("state", 1, 16);
  try {
    s.state = job_state_from_name(state);
  } catch (const InputError& e) {
    throw InputError(f.key_path("state") + ": " + e.what());
  }
  s.priority = static_cast<int>(f.integer("priority", -kMax, kMax));
  s.order = f.unsigned64("order");
  s.frames = static_cast<int>(f.integer("frames", 1, kMax));
  s.frames_done = static_cast<int>(f.integer("frames_done", 0, s.frames));
  constexpr int64_t kMaxRows = std::numeric_limits<int64_t>::max();
  s.rows_done = f.integer("rows_done", 0, kMaxRows);
  s.rows_total = f.integer("rows_total", 0, kMaxRows);
  s.resumed_rows = f.integer("resumed_rows", 0, kMaxRows);
  s.rerendered_rows = f.integer("rerendered_rows", 0, kMaxRows);
  f.read("error", s.error);
  f.read("idempotency_key", s.idempotency_key, kMaxIdempotencyKey);
  f.read("body_hash", s.body_hash, 16);
  f.finish();
  return s;
}

JobStore::JobStore(std::string dir, const std::function<void(const std::string&)>& log,
                   std::chrono::milliseconds lock_wait, const std::atomic<bool>* stop)
    : dir_(std::move(dir)) {
  std::error_code ec;
  fs::create_directories(dir_, ec);
  if (ec) throw InputError(dir_ + ": cannot create the state folder (" + ec.message() + ")");
  const std::string version_file = marker_path();
  if (!present(version_file)) require_new_state_folder(dir_, version_file);
  // Checked on its own: a file or a link in its place is named, not DIR.
  const fs::path jobs = fs::path(dir_) / "jobs";
  if (!present(jobs)) fs::create_directory(jobs, ec);
  if (ec) throw InputError(jobs.string() + ": cannot create the jobs folder (" + ec.message() + ")");
  if (fs::symlink_status(jobs, ec).type() != fs::file_type::directory)
    throw InputError(jobs.string() + ": " + kind_of(jobs) + ", not a folder");
  lock_.emplace(dir_, lock_wait, log, stop);
  if (restore_marker()) return;
  require_regular(version_file);
  const json version_json = read_json_file(version_file);
  JsonFields f(version_json, version_file);
  if (f.string("format", 0, 64) != "rayfarm-state") throw InputError(version_file + ": not a rayfarm state folder");
  const int64_t v = f.integer("version", 0, 1 << 30);
  if (v != kStateVersion)
    throw InputError(dir_ + ": state format version " + std::to_string(v) + "; this rayfarm reads version " +
                     std::to_string(kStateVersion));
  // A folder from before last-id existed has none: its job folders tell the ids (JobService).
  const std::string last_id_file = dir_ + "/last-id";
  if (!present(last_id_file)) return;
  require_regular(last_id_file);
  const std::string text = read_text_file(last_id_file, 64);
  size_t end = 0;
  try {
    if (!text.empty() && std::isdigit(static_cast<unsigned char>(text[0]))) last_id_ = std::stoull(text, &end);
  } catch (const std::out_of_range&) {
    end = 0;
  }
  if (end == 0 || text.find_first_not_of(" \t\r\n", end) != std::string::npos)
    throw InputError(last_id_file + ": expected the highest job id given out, found '" + text +
                     "' (remove the file to go on from the highest job folder)");
}

JobStore::~JobStore() = default;

bool JobStore::restore_marker() {
  if (present(marker_path())) return false;
  write_text_file(marker_path(), json{{"format", "rayfarm-state"}, {"version", kStateVersion}}.dump(2) + "\n");
  return true;
}

std::string JobStore::job_dir(uint64_t id) const { return dir_ + "/jobs/" + std::to_string(id); }

std::vector<StoredJob> JobStore::load(std::vector<SetAside>& damaged, std::vector<Incomplete>& incomplete) {
  // Listed first: folders set aside below leave the directory being read.
  std::vector<std::string> folders;
  std::vector<std::pair<std::string, std::string>> lost_status;  // folder, the files it holds
  std::vector<std::string> linked;  // jobs/ID as a symbolic link: its files would be written where it points
  for (const auto& entry : fs::directory_iterator(fs::path(dir_) / "jobs")) {
    const std::string d = entry.path().string();
    const fs::file_type type = entry.symlink_status().type();
    if (type == fs::file_type::symlink) linked.push_back(d);
    if (type != fs::file_type::directory) continue;
    if (present(d + "/status.json")) {
      folders.push_back(d);
      continue;
    }
    // Without a status and with nothing beside its submission the broker
    // crashed while creating the job, before its id was given out. Frames, a
    // journal or records mean the job ran: its status was lost, not the job.
    const std::string held = files_beside_submission(d);
    if (!held.empty())
      lost_status.emplace_back(d, held);
    else
      incomplete.push_back(remove_incomplete(d));
  }
  for (const std::string& d : linked) damaged.push_back(move_aside(d, kind_of(d) + ", not a folder"));
  for (const auto& [d, held] : lost_status)
    damaged.push_back(move_aside(d, "status.json: missing, though the folder holds " + held));
  std::vector<StoredJob> out;
  for (const std::string& d : folders) {
    try {
      out.push_back(load_job(d));
    } catch (const JournalError& e) {
      // Not the journal's content (a permission, a read-only mount, too many
      // open files): set aside for it, the job would lose rows that are still
      // good. The operator hears which file and why, and starts again.
      throw JournalError(std::string(e.what()) + "; the job (" + d +
                         ") stays in place, the service does not start until its journal can be opened");
    } catch (const std::exception& e) {
      damaged.push_back(move_aside(d, e.what()));
    }
  }
  return out;
}

std::vector<LeftTemporary> JobStore::remove_temporaries() {
  std::vector<fs::path> folders{dir_};
  for (const auto& entry : fs::directory_iterator(fs::path(dir_) / "jobs"))
    if (entry.symlink_status().type() == fs::file_type::directory) folders.push_back(entry.path());
  std::vector<LeftTemporary> out;
  for (const fs::path& folder : folders) {
    std::error_code ec;
    for (const auto& entry : fs::directory_iterator(folder, ec)) {
      const std::string of = temporary_of(entry.path().filename().string());
      if (of.empty() || entry.symlink_status().type() != fs::file_type::regular) continue;
      LeftTemporary left{entry.path().string(), of, ""};
      std::error_code removed;
      fs::remove(entry.path(), removed);
      if (removed) left.error = removed.message();
      out.push_back(std::move(left));
    }
  }
  std::sort(out.begin(), out.end(), [](const LeftTemporary& a, const LeftTemporary& b) { return a.path < b.path; });
  return out;
}

// Nothing of it was answered to a client (its id is given out with its
// status), and nothing rendered: it goes, not set aside for an operator.
Incomplete JobStore::remove_incomplete(const std::string& folder) {
  Incomplete out{folder, present(folder + "/submission.json") ? "only its submission" : "nothing", ""};
  std::error_code ec;
  fs::remove_all(folder, ec);
  if (ec) out.error = ec.message();
  return out;
}

StoredJob JobStore::load_job(const std::string& d) {
  require_regular_files(d);
  StoredJob job;
  job.status = parse_status(read_json_file(d + "/status.json"), d + "/status.json");
  // Its files are written to jobs/ID by the id in its status.
  if (fs::path(d).filename() != std::to_string(job.status.id))
    throw InputError(d + "/status.json: names job " + std::to_string(job.status.id) + ", not the job of its folder");
  if (is_finished(job.status.state)) {
    try {
      const std::vector<std::string> first = scene_names(job.status.id, true);
      if (!first.empty()) job.first_scene = first.front();
    } catch (const InputError&) {
      // Said when its names are asked for (JobService::status): the job's
      // status and frames are still good, and the start stays quick.
    }
  } else {
    job.submission = read_json_file(d + "/submission.json");
  }
  if (is_finished(job.status.state) && present(d + "/rows.journal")) {
    // Nothing reads it again, and it would stay for good.
    std::error_code ec;
    fs::remove(d + "/rows.journal", ec);
    job.leftover_journal = ec ? "cannot be removed (" + ec.message() + "); it stays, unread" : "removed";
  }
  if (!is_finished(job.status.state) && fs::exists(d + "/rows.journal")) {
    auto journal = std::make_unique<Journal>(d + "/rows.journal", job.journal);
    // A record that passes its checksum yet does not decode says nothing of
    // the others: each of them is as whole as before. Only it is skipped (its
    // rows rendered again), where the job used to be set aside, every row with it.
    uint64_t at = kJournalHeaderBytes;
    for (size_t i = 0; i < job.journal.records.size(); ++i) {
      const std::string& rec = job.journal.records[i];
      if (i == 0 && rec.compare(0, sizeof kOwnerTag, kOwnerTag, sizeof kOwnerTag) == 0) {
        job.journal_owner = rec.substr(sizeof kOwnerTag);
        at += 8 + rec.size();
        continue;
      }
      try {
        auto r = decode_journal_record(rec);
        if (auto* band = std::get_if<RowBand>(&r))
          job.rows.push_back(std::move(*band));
        else
          job.sent.push_back(std::get<RowsSent>(r));
      } catch (const InputError& e) {
        if (job.unreadable_records++ == 0)
          job.unreadable_reason =
              "record " + std::to_string(i + 1) + " at byte " + std::to_string(at) + ": " + e.what();
      }
      at += 8 + rec.size();
    }
    job.journal.records.clear();
    journals_[job.status.id] = std::move(journal);
  }
  return job;
}

SetAside JobStore::set_aside(uint64_t id, const std::string& reason) {
  close_journal(id, false);
  return move_aside(job_dir(id), reason);
}

SetAside JobStore::move_aside(const std::string& folder, std::string reason) {
  // The reason's paths point into the folder that moves: named from inside it.
  if (reason.rfind(folder + "/", 0) == 0) reason.erase(0, folder.size() + 1);
  const fs::path damaged = fs::path(dir_) / "damaged";
  const std::string name = fs::path(folder).filename().string();
  fs::path to = damaged / name;
  for (int n = 2; fs::exists(to); ++n) to = damaged / (name + "-" + std::to_string(n));  // one set aside before is kept
  std::error_code ec;
  fs::create_directories(damaged, ec);
  if (!ec) fs::rename(folder, to, ec);
  if (ec)
    throw InputError(folder + ": cannot restore the job: " + reason + "; cannot move it to " + to.string() + " (" +
                     ec.message() + ")");
  return SetAside{folder, to.string(), reason};
}

uint64_t JobStore::next_id() const {
  uint64_t next = last_id_ + 1;
  std::error_code ec;  // no DIR/damaged: nothing was set aside
  for (const auto& entry : fs::directory_iterator(fs::path(dir_) / "damaged", ec)) {
    const std::string name = entry.path().filename().string();  // ID, or ID-2 for a second one
    const size_t digits = std::min(name.find_first_not_of("0123456789"), name.size());
    if (digits == 0 || digits > 19) continue;
    next = std::max<uint64_t>(next, std::stoull(name.substr(0, digits)) + 1);
  }
  return next;
}

void JobStore::create(const JobStatus& status, const json& submission) {
  {
    // Before the job's folder: once that is removed, the id is still known as given out.
    std::lock_guard<std::mutex> lock(last_id_mutex_);
    if (status.id > last_id_) {
      write_text_file(dir_ + "/last-id", std::to_string(status.id) + "\n");
      last_id_ = status.id;
    }
  }
  const std::string d = job_dir(status.id);
  std::error_code ec;
  fs::create_directories(d, ec);
  if (ec) throw std::runtime_error(d + ": cannot create (" + ec.message() + ")");
  try {
    write_text_file(d + "/submission.json", submission.dump());
    save_status(status);  // last: a job exists once its status does
  } catch (...) {
    // A folder without its status is no job: left behind (empty, or a
    // submission alone) it stayed in jobs/ for ever, listed nowhere.
    fs::remove_all(d, ec);
    throw;
  }
}

void JobStore::save_status(const JobStatus& status) {
  // The key is the store's, not the API's: a job's status answers without it.
  json j = status_json(status);
  if (!status.idempotency_key.empty()) {
    j["idempotency_key"] = status.idempotency_key;
    j["body_hash"] = status.body_hash;
  }
  write_text_file(job_dir(status.id) + "/status.json", j.dump(2) + "\n");
}

json JobStore::read_submission(uint64_t id) const { return read_json_file(job_dir(id) + "/submission.json"); }

std::vector<std::string> JobStore::scene_names(uint64_t id, bool first_only) const {
  const std::string path = job_dir(id) + "/submission.json";
  require_regular(path);  // a FIFO put there would block the caller for good
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path + ": cannot open (" + std::strerror(errno) + ")");
  return scene_names_in(in, path, first_only);
}

Journal& JobStore::journal_of(uint64_t id, const std::string& owner) {
  auto it = journals_.find(id);
  if (it == journals_.end()) {
    JournalRecovery ignored;  // a job's journal is read by load() before its rows are written
    // Opened before it is kept: one that cannot be opened leaves no empty entry behind.
    it = journals_.emplace(id, std::make_unique<Journal>(journal_path(id), ignored)).first;
  }
  if (it->second->size() == kJournalHeaderBytes) it->second->append(encode_journal_owner(owner));  // a new one
  return *it->second;
}

std::string JobStore::set_journal_aside(uint64_t id) {
  close_journal(id, false);
  const std::string from = journal_path(id);
  std::string to = from + ".foreign";
  for (int n = 2; present(to); ++n) to = from + ".foreign-" + std::to_string(n);  // one set aside before is kept
  std::error_code ec;
  fs::rename(from, to, ec);
  if (ec) throw InputError(from + ": cannot move it aside to " + to + " (" + ec.message() + ")");
  return to;
}

void JobStore::close_journal(uint64_t id, bool remove) {
  journals_.erase(id);
  if (remove) fs::remove(journal_path(id));
}

std::string JobStore::journal_path(uint64_t id) const { return job_dir(id) + "/rows.journal"; }

uint64_t JobStore::journal_bytes(uint64_t id) const {
  auto it = journals_.find(id);
  return it == journals_.end() ? 0 : it->second->size();
}

std::string JobStore::frame_path(uint64_t id, uint32_t frame) const {
  return job_dir(id) + "/" + numbered("frame", frame, "rgbf");
}

std::string JobStore::record_path(uint64_t id, uint32_t frame) const {
  return job_dir(id) + "/" + numbered("record", frame, "json");
}

void JobStore::write_frame(uint64_t id, uint32_t frame, int width, int height, const std::vector<float>& rgb) {
  write_text_file(frame_path(id, frame), encode_frame(width, height, rgb));
}

void JobStore::write_record(uint64_t id, uint32_t frame, const json& record) {
  write_text_file(record_path(id, frame), record.dump(2) + "\n");
}

void JobStore::write_note(const std::string& name, const std::string& text) {
  // A whole-file write goes through a symbolic link (output_file.h), here to
  // wherever it points, outside the state folder: a note is rewritten at each
  // start, so the link is replaced by a file of its own.
  const std::string path = dir_ + "/" + name;
  std::error_code ec;
  if (fs::is_symlink(fs::symlink_status(path, ec))) fs::remove(path, ec);
  write_text_file(path, text);
}

}  // namespace rayfarm
