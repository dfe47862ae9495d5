// The job queue's rules; see job_queue.h.
#include "service/job_queue.h"

#include <algorithm>
#include <stdexcept>

#include "tracer/error.h"

namespace rayfarm {

const char* job_state_name(JobState s) {
  switch (s) {
    case JobState::queued: return "queued";
    case JobState::running: return "running";
    case JobState::done: return "done";
    case JobState::failed: return "failed";
    case JobState::cancelled: return "cancelled";
  }
  return "?";
}

JobState job_state_from_name(const std::string& name) {
  for (JobState s : {JobState::queued, JobState::running, JobState::done, JobState::failed, JobState::cancelled})
    if (name == job_state_name(s)) return s;
  throw InputError("unknown job state '" + name + "'");
}

bool is_finished(JobState s) { return s == JobState::done || s == JobState::failed || s == JobState::cancelled; }

void JobQueue::add(const JobStatus& job) {
  if (!jobs_.emplace(job.id, job).second) throw std::logic_error("job " + std::to_string(job.id) + " added twice");
}

std::optional<uint64_t> JobQueue::next() const {
  for (const auto& [id, j] : jobs_)
    if (j.state == JobState::running) return id;
  return after(0);
}

std::optional<uint64_t> JobQueue::after(uint64_t current) const {
  const JobStatus* best = nullptr;
  for (const auto& [id, j] : jobs_) {
    if (j.state != JobState::queued || id == current) continue;
    if (!best || j.priority > best->priority || (j.priority == best->priority && j.order < best->order)) best = &j;
  }
  return best ? std::optional<uint64_t>(best->id) : std::nullopt;
}

JobStatus& JobQueue::at(uint64_t id, JobState expected) {
  JobStatus& j = jobs_.at(id);
  if (j.state != expected)
    throw std::logic_error("job " + std::to_string(id) + " is " + job_state_name(j.state) + ", expected " +
                           job_state_name(expected));
  return j;
}

void JobQueue::start(uint64_t id) { at(id, JobState::queued).state = JobState::running; }

void JobQueue::frame_done(uint64_t id) {
  JobStatus& j = at(id, JobState::running);
  if (++j.frames_done == j.frames) j.state = JobState::done;
}

void JobQueue::fail(uint64_t id, const std::string& reason) {
  JobStatus& j = jobs_.at(id);
  if (is_finished(j.state)) return;
  j.state = JobState::failed;
  j.error = reason;
}

bool JobQueue::cancel(uint64_t id, const std::string& reason) {
  JobStatus& j = jobs_.at(id);
  if (is_finished(j.state)) return false;
  j.state = JobState::cancelled;
  j.error = reason;
  return true;
}

void JobQueue::put_back(const JobStatus& before) { jobs_.at(before.id) = before; }

void JobQueue::add_rows(uint64_t id, int64_t rows, bool resumed) {
  JobStatus& j = jobs_.at(id);
  j.rows_done += rows;
  if (resumed) j.resumed_rows += rows;
}

void JobQueue::add_rerendered(uint64_t id, int64_t rows) { jobs_.at(id).rerendered_rows += rows; }

std::vector<JobStatus> JobQueue::list() const {
  std::vector<JobStatus> out;
  for (const auto& [id, j] : jobs_) out.push_back(j);
  std::sort(out.begin(), out.end(), [](const JobStatus& a, const JobStatus& b) { return a.order < b.order; });
  return out;
}

}  // namespace rayfarm
