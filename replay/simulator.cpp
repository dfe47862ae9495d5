// The dispatch replay; see simulator.h. Mirrors broker/broker.cpp: dispatch()
// runs after every batch of messages that arrive together.
#include "replay/simulator.h"

#include <algorithm>
#include <cstdint>
#include <numeric>
#include <queue>
#include <stdexcept>

#include "broker/broker_config.h"
#include "broker/row_order.h"

namespace rayfarm {
namespace {

// A message reaching the broker: a machine's job_ready, or a task's result.
struct Event {
  double time = 0;
  uint64_t seq = 0;  // ties keep the order events were created in
  int machine = 0;
  int task = -1;     // -1 = job_ready
  bool operator>(const Event& o) const { return time != o.time ? time > o.time : seq > o.seq; }
};

struct MachineState {
  bool loaded = false;
  int in_flight = 0;
  double last_result = 0;  // the broker's longest-idle key (registration time before any result)
  double free_at = 0;      // when the machine finishes its queued work
};

class Replay {
 public:
  Replay(const RowCosts& costs, const std::vector<SimMachine>& machines, const SimOptions& o)
      : costs_(costs), machines_(machines), o_(o), state_(machines.size()), rows_(costs.height()) {
    BrokerConfig sizing;  // the broker's own task sizing, so the replay cannot drift from it
    sizing.reference_weight = o.reference_weight;
    sizing.base_task_rows = o.base_task_rows;
    for (const SimMachine& m : machines) {
      MachineResult r;
      r.name = m.name;
      r.type = m.type;
      r.weight = m.weight;
      r.speed = m.speed;
      r.credit = m.credit;
      r.task_rows = task_rows_for(sizing, o.weighted ? m.weight : o.reference_weight);
      result_.machines.push_back(r);
    }
  }

  SimResult run() {
    for (size_t i = 0; i < machines_.size(); ++i) {
      // Announcement out, init, job_ready back.
      const double ready = i * o_.stagger_s + machines_[i].init_s + 2 * o_.latency_s;
      push(ready, static_cast<int>(i), -1);
    }
    double first_dispatch = -1;
    while (!events_.empty()) {
      const double now = events_.top().time;
      while (!events_.empty() && events_.top().time == now) {
        const Event e = events_.top();
        events_.pop();
        arrive(e);
      }
      if (dispatch(now) && first_dispatch < 0) first_dispatch = now;
    }
    finish(first_dispatch);
    return result_;
  }

 private:
  void push(double time, int machine, int task) { events_.push(Event{time, seq_++, machine, task}); }

  void arrive(const Event& e) {
    MachineState& s = state_[static_cast<size_t>(e.machine)];
    MachineResult& r = result_.machines[static_cast<size_t>(e.machine)];
    if (e.task < 0) {
      s.loaded = true;
      r.ready_at = e.time;
      return;
    }
    s.in_flight -= 1;
    s.last_result = e.time;
    r.last_done = e.time;
    result_.makespan_s = std::max(result_.makespan_s, e.time);
  }

  // The broker's dispatch(): longest-idle first, one task per machine per pass,
  // until credits or rows run out. True if any task went out.
  bool dispatch(double now) {
    std::vector<int> order;
    for (size_t i = 0; i < state_.size(); ++i)
      if (state_[i].loaded && state_[i].in_flight < machines_[i].credit) order.push_back(static_cast<int>(i));
    std::stable_sort(order.begin(), order.end(),
                     [&](int a, int b) { return state_[static_cast<size_t>(a)].last_result < state_[static_cast<size_t>(b)].last_result; });
    bool any = false, gave = true;
    while (gave) {
      gave = false;
      for (int i : order) {
        if (state_[static_cast<size_t>(i)].in_flight >= machines_[static_cast<size_t>(i)].credit) continue;
        if (rows_.remaining() == 0) return any;
        send_task(i, now);
        any = gave = true;
      }
    }
    return any;
  }

  void send_task(int i, double now) {
    MachineState& s = state_[static_cast<size_t>(i)];
    MachineResult& r = result_.machines[static_cast<size_t>(i)];
    SimTask t;
    t.machine = i;
    const auto band = rows_.take(r.task_rows);  // the broker's own row order
    t.y0 = band->first;
    t.y1 = band->second;
    const double busy = costs_.sum(t.y0, t.y1) / machines_[static_cast<size_t>(i)].speed;
    t.dispatched = now;
    t.started = std::max(now + o_.latency_s, s.free_at);  // queued behind earlier tasks (credit)
    s.free_at = t.started + busy;
    t.finished = s.free_at + o_.latency_s;
    s.in_flight += 1;
    r.tasks += 1;
    r.rows += t.y1 - t.y0;
    r.busy_s += busy;
    push(t.finished, i, static_cast<int>(tasks_sent_++));
    if (o_.keep_tasks) result_.tasks.push_back(t);
  }

  void finish(double first_dispatch) {
    SimResult& res = result_;
    res.first_ready_s = res.machines.empty() ? 0 : res.machines.front().ready_at;
    for (const MachineResult& m : res.machines) {
      res.first_ready_s = std::min(res.first_ready_s, m.ready_at);
      res.work_s += m.busy_s * m.speed;
      res.normalized += m.speed;
    }
    res.render_s = res.makespan_s - std::max(0.0, first_dispatch);
    res.sequential_s = o_.sequential_init_s + costs_.total();
    res.speedup = res.makespan_s > 0 ? res.sequential_s / res.makespan_s : 0;
    res.efficiency = res.normalized > 0 ? res.speedup / res.normalized : 0;
  }

  const RowCosts& costs_;
  const std::vector<SimMachine>& machines_;
  SimOptions o_;
  std::vector<MachineState> state_;
  std::priority_queue<Event, std::vector<Event>, std::greater<Event>> events_;
  uint64_t seq_ = 0;
  uint64_t tasks_sent_ = 0;
  RowCursor rows_;
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

}  // namespace rayfarm
