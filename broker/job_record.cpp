// Job record JSON; see job_record.h.
#include "broker/job_record.h"

#include "protocol/codec.h"

namespace rayfarm {
namespace {

using nlohmann::json;

json task_json(const TaskRecord& t) {
  json attempts = json::array();
  for (const TaskAttempt& a : t.attempts)
    attempts.push_back({{"attempt", a.attempt}, {"worker", a.worker_name}, {"dispatched", a.dispatched},
                        {"finished", a.finished}, {"backup", a.backup}, {"outcome", a.outcome}});
  const TaskAttempt& last = t.final_attempt();
  return {{"task", t.id},         {"y0", t.y0},
          {"y1", t.y1},           {"rows", t.rows()},
          {"worker", last.worker_name}, {"attempt", last.attempt},
          {"dispatched", last.dispatched}, {"started", t.started},
          {"finished", t.finished}, {"render_s", t.render_s},
          {"throttle_s", t.throttle_s}, {"attempts", attempts}};
}

json worker_json(const WorkerRecord& w) {
  return {{"name", w.name},         {"weight", w.weight},         {"threads", w.threads},
          {"credit", w.credit},     {"throttle", w.throttle},     {"task_rows", w.task_rows},
          {"tasks", w.tasks},       {"rows", w.rows},             {"tasks_lost", w.tasks_lost},
          {"init_s", w.init_s},     {"ready_at", w.ready_at},     {"busy_s", w.busy_s},
          {"render_s", w.render_s}, {"throttle_s", w.throttle_s}, {"speed", w.speed}, {"state", w.state}};
}

}  // namespace

json make_job_record(const JobRecordInput& in) {
  const RenderSettings& s = in.settings;
  json tasks = json::array();
  int reissued = 0, rows_reissued = 0;
  for (const TaskRecord& t : in.board->tasks()) {
    tasks.push_back(task_json(t));
    reissued += t.attempts.size() > 1;
    rows_reissued += t.attempts.size() > 1 ? t.rows() : 0;
  }
  json workers = json::array();
  for (const WorkerRecord& w : in.workers) workers.push_back(worker_json(w));
  return {
      {"job", in.job},
      {"scene", in.scene_name},
      {"scene_hash", protocol::hash_hex(in.scene_hash)},
      {"settings",
       {{"width", s.width}, {"height", s.height}, {"spp", s.spp}, {"max_depth", s.max_depth}, {"seed", s.seed},
        {"adaptive_contrast", s.adaptive_contrast}, {"cutoff", s.cutoff}, {"robust_bvh", s.robust_bvh}}},
      {"reference_weight", in.reference_weight},
      {"base_task_rows", in.base_task_rows},
      {"policy", in.policy},
      {"backups", in.backups},
      {"init_s", in.times.init_s},
      {"render_s", in.times.render_s},
      {"total_s", in.times.total_s},
      {"rays",
       {{"eye", in.stats.eye}, {"eye_hit", in.stats.eye_hit}, {"shadow", in.stats.shadow},
        {"reflection", in.stats.reflection}, {"refraction", in.stats.refraction}, {"total", in.stats.total()}}},
      {"non_finite_samples", in.stats.non_finite},
      {"task_count", in.board->tasks().size()},
      {"tasks_reissued", reissued},
      {"rows_reissued", rows_reissued},               // rendered more than once (lost tasks)
      {"resumed_rows", in.board->rows_restored()},    // restored after a broker restart
      {"rejected", in.rejected},
      {"workers", workers},
      {"tasks", tasks},
  };
}

}  // namespace rayfarm
