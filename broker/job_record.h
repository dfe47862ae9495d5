// The job record: what happened during one distributed render, as JSON. Per
// task: rows and pixels (x0, x1: the whole row, or a span of one), the worker
// and attempt that finished it, dispatch/start/finish times and every earlier
// attempt (a lost task shows attempt 1 "lost" and attempt 2 "done"). Per
// worker: name and id (NAME#SERIAL, as the broker's log names it), weight, task size, tasks, rows, spans, busy and throttle
// seconds; registrations that ended before being handed a task are only
// counted (registrations_without_tasks). Times are seconds since the job was announced (broker clock).
// A job resumed after a broker restart counts its restored rows (resumed_rows);
// they have no tasks in this record.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "broker/task_board.h"
#include "tracer/ray_stats.h"
#include "tracer/render_settings.h"

namespace rayfarm {

// One registration of a worker during a job.
struct WorkerRecord {
  uint32_t serial = 0;
  std::string name;
  double weight = 0;
  int threads = 0;
  int credit = 0;
  double throttle = 1;
  int task_rows = 1;
  int tasks = 0;
  int rows = 0;   // a row rendered in spans counts for the worker whose span completed it
  int spans = 0;  // tasks that were pixel spans of a row
  int tasks_lost = 0;
  double init_s = -1;     // worker-side parse + BVH build, -1 = never ready
  double ready_at = -1;   // when its job_ready arrived
  double busy_s = 0;      // render + throttle seconds over accepted tasks
  double render_s = 0;
  double throttle_s = 0;
  double speed = 0;       // the dispatch policy's final view: declared, or measured if it differs
  std::string state = "active";  // "active", "lost" (heartbeat timeout), "left" (bye/re-register),
                                 // "failed" (job_failed), "excluded" (results it sent could not be used)
};

struct JobTimes {
  double init_s = 0;    // announce -> first worker ready
  double render_s = 0;  // first dispatch -> last result
  double total_s = 0;   // announce -> image assembled
};

struct JobRecordInput {
  uint64_t job = 0;
  std::string scene_name;
  uint64_t scene_hash = 0;
  RenderSettings settings;
  double reference_weight = 21;
  int base_task_rows = 1;
  std::string policy;  // broker/dispatch_policy.h
  int backups = 0;     // backup attempts issued
  JobTimes times;
  RayStats stats;
  const TaskBoard* board = nullptr;
  std::vector<WorkerRecord> workers;
  std::map<std::string, int> rejected;  // reason -> count
  // Registrations that ended (left, lost, re-registered) before being handed
  // any task, and did not fail the job: counted here, not listed in `workers`.
  int registrations_without_tasks = 0;
};

// How logs and records tell registrations apart: "NAME#SERIAL". Two workers
// may share a --name (or one may register twice); the serial never repeats.
std::string worker_id(const std::string& name, uint32_t serial);

nlohmann::json make_job_record(const JobRecordInput& in);

}  // namespace rayfarm
