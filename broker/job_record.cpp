// Job record JSON; see job_record.h.
#include "broker/job_record.h"

#include <algorithm>

#include "protocol/codec.h"

namespace rayfarm {
namespace {

using nlohmann::json;

// Task objects are filled by emplace into the underlying map: nlohmann's
// initializer-list form builds a two-element array per key first, and the
// record holds every task of the job (for 65,536 one-row tasks that took the
// broker longer than dispatching them).
class ObjectBuilder {
 public:
  ObjectBuilder() : json_(json::value_t::object), map_(*json_.get_ptr<json::object_t*>()) {}
  template <class T> ObjectBuilder& add(const char* key, T&& value) {
    map_.emplace(key, std::forward<T>(value));
    return *this;
  }
  json done() { return std::move(json_); }

 private:
  json json_;
  json::object_t& map_;
};

json task_json(const TaskRecord& t) {
  json attempts(json::value_t::array);
  attempts.get_ptr<json::array_t*>()->reserve(t.attempts.size());
  for (const TaskAttempt& a : t.attempts)
    attempts.push_back(ObjectBuilder()
                           .add("attempt", a.attempt)
                           .add("worker", a.worker_name)
                           .add("worker_id", worker_id(a.worker_name, a.worker))
                           .add("dispatched", a.dispatched)
                           .add("finished", a.finished)
                           .add("backup", a.backup)
                           .add("outcome", a.outcome)
                           .done());
  const TaskAttempt& last = t.final_attempt();
  return ObjectBuilder()
      .add("task", t.id)
      .add("y0", t.y0)
      .add("y1", t.y1)
      .add("x0", t.x0)
      .add("x1", t.x1)
      .add("rows", t.rows())
      .add("worker", last.worker_name)
      .add("worker_id", worker_id(last.worker_name, last.worker))
      .add("attempt", last.attempt)
      .add("dispatched", last.dispatched)
      .add("started", t.started)
      .add("finished", t.finished)
      .add("render_s", t.render_s)
      .add("throttle_s", t.throttle_s)
      .add("attempts", std::move(attempts))
      .done();
}

json worker_json(const WorkerRecord& w) {
  return {{"name", w.name},         {"id", worker_id(w.name, w.serial)},
          {"weight", w.weight},     {"threads", w.threads},
          {"credit", w.credit},     {"throttle", w.throttle},     {"task_rows", w.task_rows},
          {"tasks", w.tasks},       {"rows", w.rows},             {"spans", w.spans},
          {"tasks_lost", w.tasks_lost},
          {"init_s", w.init_s},     {"ready_at", w.ready_at},     {"busy_s", w.busy_s},
          {"render_s", w.render_s}, {"throttle_s", w.throttle_s}, {"speed", w.speed}, {"state", w.state}};
}

}  // namespace

std::string worker_id(const std::string& name, uint32_t serial) { return name + "#" + std::to_string(serial); }

json make_job_record(const JobRecordInput& in) {
  const RenderSettings& s = in.settings;
  json tasks(json::value_t::array);
  tasks.get_ptr<json::array_t*>()->reserve(in.board->tasks().size());
  // Re-issued: handed out again once every attempt of it was lost (a worker
  // gone), its rows rendered again because no result came. Backed up: given a
  // backup attempt while its first was still live (a straggler), whichever
  // result came first kept. Apart, so that a farm without failures shows no
  // rows rendered again, only the price of its backups.
  int reissued = 0, backed_up = 0;
  int64_t pixels_reissued = 0, pixels_backed_up = 0;
  for (const TaskRecord& t : in.board->tasks()) {
    tasks.push_back(task_json(t));
    const auto again = [](const TaskAttempt& a) { return a.attempt > 1 && !a.backup; };
    if (std::any_of(t.attempts.begin(), t.attempts.end(), again)) ++reissued, pixels_reissued += t.pixels();
    if (std::any_of(t.attempts.begin(), t.attempts.end(), [](const TaskAttempt& a) { return a.backup; }))
      ++backed_up, pixels_backed_up += t.pixels();
  }
  // In rows' worth of pixels, rounded up: a span counts its share of a row.
  const auto rows_of = [&](int64_t pixels) { return (pixels + s.width - 1) / s.width; };
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
      {"rows_reissued", rows_of(pixels_reissued)},  // rendered again, their first result lost
      {"pixels_reissued", pixels_reissued},
      {"tasks_backed_up", backed_up},
      {"rows_backed_up", rows_of(pixels_backed_up)},  // given a backup copy (a straggler's)
      {"pixels_backed_up", pixels_backed_up},
      {"resumed_rows", in.board->rows_restored()},    // restored after a broker restart
      {"rejected", in.rejected},
      {"workers", workers},
      {"registrations_without_tasks", in.registrations_without_tasks},
      {"tasks", tasks},
  };
}

}  // namespace rayfarm
