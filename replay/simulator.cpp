// The dispatch replay; see simulator.h. The event loop stands in for the
// broker's socket loop: arrivals at one instant are handled together, then
// the shared DispatchPolicy hands out work.
#include "replay/simulator.h"

#include <algorithm>
#include <cstdint>
#include <queue>
#include <stdexcept>

namespace rayfarm {
namespace {

// Something reaching the broker: a machine's job_ready, a task's result, or
// the broker noticing that a machine fell silent.
struct Event {
  enum Kind { ready, result, lost } kind = ready;
  double time = 0;
  uint64_t seq = 0;  // ties keep the order events were created in
  int machine = 0;
  uint32_t task = 0, attempt = 0;
  double busy = 0;
  size_t sim_task = 0;  // index into SimResult::tasks when kept
  bool operator>(const Event& o) const { return time != o.time ? time > o.time : seq > o.seq; }
};

uint32_t serial_of(size_t machine) { return static_cast<uint32_t>(machine + 1); }

class Replay {
 public:
  Replay(const RowCosts& costs, const std::vector<SimMachine>& machines, const SimOptions& o)
      : costs_(costs), machines_(machines), o_(o), board_(costs.height(), std::max(1, costs.width)), policy_(policy_options(o, costs), board_),
        free_at_(machines.size(), 0.0) {
    for (size_t i = 0; i < machines.size(); ++i) {
      const SimMachine& m = machines[i];
      MachineResult r;
      r.name = m.name;
      r.type = m.type;
      r.weight = m.weight;
      r.speed = m.speed;
      r.credit = o.policy == PolicyKind::paper ? 1 : m.credit;
      r.task_rows = nominal_task_rows(policy_options(o, costs), m.weight);
      result_.machines.push_back(r);
      policy_.add_worker(serial_of(i), m.name, m.weight, m.credit);
    }
  }

  SimResult run() {
    for (size_t i = 0; i < machines_.size(); ++i) {
      // Announcement out, init, job_ready back.
      const double ready = i * o_.stagger_s + machines_[i].init_s + 2 * o_.latency_s;
      if (!lost_before(i, ready)) push(Event{Event::ready, ready, 0, static_cast<int>(i)});
      if (machines_[i].lost_at >= 0) push(Event{Event::lost, machines_[i].lost_at + o_.loss_detect_s, 0, static_cast<int>(i)});
    }
    double first_dispatch = -1;
    std::vector<Dispatch> out;
    while (!events_.empty() && !board_.complete()) {
      const double now = events_.top().time;
      while (!events_.empty() && events_.top().time == now) {
        const Event e = events_.top();
        events_.pop();
        arrive(e);
      }
      if (board_.complete()) break;
      out.clear();
      policy_.dispatch(now, out);
      for (const Dispatch& d : out) send_task(d, now);
      if (!out.empty() && first_dispatch < 0) first_dispatch = now;
    }
    if (!board_.complete()) throw std::runtime_error("simulate: every machine was lost before the image was done");
    finish(first_dispatch);
    return result_;
  }

 private:
  static PolicyOptions policy_options(const SimOptions& o, const RowCosts& costs) {
    PolicyOptions p;
    p.kind = o.policy;
    p.reference_weight = o.reference_weight;
    p.base_task_rows = o.base_task_rows;
    p.latency_s = o.latency_s;
    p.min_span_pixels = o.min_span_pixels;
    if (o.prior_frame) p.prior_costs = costs.rows;
    return p;
  }

  bool lost_before(size_t i, double t) const { return machines_[i].lost_at >= 0 && machines_[i].lost_at < t; }

  void push(Event e) {
    e.seq = seq_++;
    events_.push(e);
  }

  void arrive(const Event& e) {
    const size_t i = static_cast<size_t>(e.machine);
    MachineResult& r = result_.machines[i];
    if (e.kind == Event::ready) {
      r.ready_at = e.time;
      policy_.worker_ready(serial_of(i), e.time);
      return;
    }
    if (e.kind == Event::lost) {
      result_.requeued += policy_.remove_worker(serial_of(i), e.time);
      return;
    }
    const TaskRecord& t = board_.task(e.task);
    const Verdict v = policy_.on_result(serial_of(i), e.task, e.attempt, t.band(), e.time, e.busy, 0);
    if (v != Verdict::accepted) {
      r.attempts_wasted += 1;
      r.wasted_s += e.busy;
      return;
    }
    r.tasks += 1;
    r.rows += static_cast<double>(t.pixels()) / board_.width();
    r.spans += t.span;
    r.busy_s += e.busy;
    r.last_done = e.time;
    r.backups_won += t.attempts[e.attempt - 1].backup;
    if (o_.keep_tasks) result_.tasks[e.sim_task].accepted = true;
    result_.makespan_s = std::max(result_.makespan_s, e.time);
  }

  void send_task(const Dispatch& d, double now) {
    const size_t i = d.worker - 1;
    // A span costs its pixels' share of the row: the profile has rows only.
    const double share = static_cast<double>(d.x1 - d.x0) / board_.width();
    const double busy = costs_.sum(d.y0, d.y1) * share / machines_[i].speed;
    SimTask t;
    t.machine = static_cast<int>(i);
    t.y0 = d.y0;
    t.y1 = d.y1;
    t.x0 = d.x0;
    t.x1 = d.x1;
    t.backup = d.backup;
    t.dispatched = now;
    t.started = std::max(now + o_.latency_s, free_at_[i]);  // queued behind earlier tasks (credit)
    free_at_[i] = t.started + busy;
    t.finished = free_at_[i] + o_.latency_s;
    if (o_.keep_tasks) result_.tasks.push_back(t);
    if (lost_before(i, free_at_[i])) return;  // the machine falls silent before it is done
    Event e{Event::result, t.finished, 0, static_cast<int>(i), d.task, d.attempt, busy};
    e.sim_task = o_.keep_tasks ? result_.tasks.size() - 1 : 0;
    push(e);
  }

  void finish(double first_dispatch) {
    SimResult& res = result_;
    res.first_ready_s = res.machines.empty() ? 0 : res.machines.front().ready_at;
    for (const MachineResult& m : res.machines) {
      res.first_ready_s = std::min(res.first_ready_s, m.ready_at);
      res.work_s += m.busy_s * m.speed;
      res.wasted_s += m.wasted_s * m.speed;
      res.normalized += m.speed;
      res.tasks_done += m.tasks;
      res.spans_done += m.spans;
    }
    res.backups = policy_.backups();
    res.render_s = res.makespan_s - std::max(0.0, first_dispatch);
    res.sequential_s = o_.sequential_init_s + costs_.total();
    res.speedup = res.makespan_s > 0 ? res.sequential_s / res.makespan_s : 0;
    res.efficiency = res.normalized > 0 ? res.speedup / res.normalized : 0;
    res.lower_bound_s = makespan_lower_bound(costs_, machines_, o_);
    res.bound_ratio = res.lower_bound_s > 0 ? res.makespan_s / res.lower_bound_s : 0;
  }

  const RowCosts& costs_;
  const std::vector<SimMachine>& machines_;
  SimOptions o_;
  TaskBoard board_;
  DispatchPolicy policy_;
  std::vector<double> free_at_;  // per machine: when its queue of tasks drains
  std::priority_queue<Event, std::vector<Event>, std::greater<Event>> events_;
  uint64_t seq_ = 0;
  SimResult result_;
};

}  // namespace

SimResult simulate(const RowCosts& costs, const std::vector<SimMachine>& machines, const SimOptions& options) {
  if (machines.empty()) throw std::invalid_argument("simulate: no machines");
  if (costs.rows.empty()) throw std::invalid_argument("simulate: empty cost profile");
  for (const SimMachine& m : machines)
    if (!(m.speed > 0) || m.credit < 1) throw std::invalid_argument("simulate: machine " + m.name + " has no speed or credit");
  return Replay(costs, machines, options).run();
}

// Water-filling: sorted by start time, find T with sum speed_i (T - start_i)
// = work over the machines started before T.
double makespan_lower_bound(const RowCosts& costs, const std::vector<SimMachine>& machines, const SimOptions& o) {
  std::vector<std::pair<double, double>> starts;  // (start, speed)
  for (size_t i = 0; i < machines.size(); ++i) {
    if (machines[i].lost_at >= 0) continue;
    starts.push_back({i * o.stagger_s + machines[i].init_s + 3 * o.latency_s, machines[i].speed});
  }
  if (starts.empty()) return 0;
  std::sort(starts.begin(), starts.end());
  const double work = costs.total();
  double speed = 0, weighted_start = 0, t = 0;
  for (size_t k = 0; k < starts.size(); ++k) {
    speed += starts[k].second;
    weighted_start += starts[k].second * starts[k].first;
    t = (work + weighted_start) / speed;  // the finish if only machines 0..k worked
    if (k + 1 == starts.size() || t <= starts[k + 1].first) break;
  }
  return t + o.latency_s;
}

}  // namespace rayfarm
