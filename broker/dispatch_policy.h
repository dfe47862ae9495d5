// DispatchPolicy: which rows each worker with a free credit gets next. Pure
// logic over the job's TaskBoard and the workers' state: no sockets, no clock
// (the caller passes `now`), so the broker and the replay (replay/simulator.h)
// run the very same decisions. Workers with free credit wait in a FIFO, the
// longest idle first, and take one task per turn (the paper's static start:
// the first N tasks go to N different workers). Policies (protocol/SPEC.md,
// "Dispatch"):
//  - paper:    constant base_task_rows rows in the row order
//              (broker/row_order.h), one task in flight per worker (Sung, Loh
//              and Ananda, section 3.3.3);
//  - weighted: rows scaled by declared weight (the paper's section 4.4.2);
//  - adaptive: a first wave of single rows over the whole image, then every
//              16th row alone (coarse to fine, for the preview), then the dearest
//              rows first when cost estimates are trusted (the previous
//              frame's costs, or interpolated ones that predicted results
//              within 25%), else in row order; task cost shrinks with the work
//              left (factoring: 1/(4 x credit x N) of it, scaled by the
//              worker's speed); a row dearer than that share is cut into
//              pixel spans of about the share (the tail of the job), left to
//              right, and the open row is finished before a new one starts;
//              speeds measured from results; no task queued
//              behind more than 50 ms of work; backup copies of straggling
//              tasks on idle workers at the end (first result wins).
#pragma once

#include <cstdint>
#include <deque>
#include <map>
#include <set>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include "broker/task_board.h"

namespace rayfarm {

enum class PolicyKind { paper, weighted, adaptive };

inline constexpr const char* kPolicyNames = "paper, weighted, adaptive";
const char* policy_name(PolicyKind kind);
// Throws InputError naming `where` and the known names.
PolicyKind parse_policy(const std::string& name, const std::string& where);

struct PolicyOptions {
  PolicyKind kind = PolicyKind::adaptive;
  double reference_weight = 21.0;  // weight of a speed-1 worker
  int base_task_rows = 1;          // paper and weighted
  double latency_s = 0;            // one-way message latency, for backup decisions
  int max_task_rows = 65536;       // adaptive tasks never grow taller (the broker's frame cap)
  // adaptive: the narrowest pixel span a row is cut into (0 = never cut rows).
  int min_span_pixels = 16;
  // Previous frame's seconds per row on a speed-1 worker; empty = learn from scratch.
  std::vector<double> prior_costs;
};

// Rows per task at `weight` for the weighted policy: max(1, round(weight /
// reference x base)), e.g. the paper's R4000 (60.3) gets 3 rows where an SSC (21) gets 1.
int weighted_task_rows(double weight, double reference_weight, int base_task_rows);
// What a worker of `weight` is given per task: base rows (paper), weighted rows,
// or 0 (adaptive: sized at each dispatch).
int nominal_task_rows(const PolicyOptions& options, double weight);

// One task sent to one worker (copied: the board's records move as it grows).
struct Dispatch {
  uint32_t worker = 0;
  uint32_t task = 0, attempt = 0;
  int y0 = 0, y1 = 0;
  int x0 = 0, x1 = 0;  // pixels of each row (the whole row unless a span)
  bool backup = false;
};

class DispatchPolicy {
 public:
  DispatchPolicy(PolicyOptions options, TaskBoard& board);

  // A worker registered (it may still be loading the scene).
  void add_worker(uint32_t serial, const std::string& name, double weight, int credit);
  // Its job_ready arrived: it joins the queue.
  void worker_ready(uint32_t serial, double now);
  // The worker is gone: its attempts are requeued on the board. Returns how many.
  int remove_worker(uint32_t serial, double now);

  // A result: judged by the board; frees the worker's credit unless the result
  // is not for one of its live attempts; an accepted one teaches costs and speed.
  Verdict on_result(uint32_t serial, uint32_t task, uint32_t attempt, const PixelBand& band, double now,
                    double render_s, double throttle_s);

  // A result the caller refused before judging it (e.g. wrong width): the
  // worker's attempt is requeued.
  void reject_result(uint32_t serial, uint32_t task, double now);

  // Hands out tasks until credits or work run out; appends to `out`.
  void dispatch(double now, std::vector<Dispatch>& out);

  // The worker's speed as the policy sees it (declared, or measured when it differs).
  double speed_of(uint32_t serial) const;
  // Live attempts the worker holds (0 for a worker the policy does not know).
  int in_flight(uint32_t serial) const;
  // Seconds per row on a speed-1 worker as learned so far (for the next frame).
  // Empty unless the adaptive policy learned them.
  std::vector<double> row_costs() const { return o_.kind == PolicyKind::adaptive && scaled_ ? cost_ : std::vector<double>{}; }
  int backups() const { return backups_; }

 private:
  struct WorkerState {
    std::string name;
    double declared = 1, speed = 1;
    double measured_cost = 0, measured_busy = 0;  // sums over accepted results
    int credit = 1, in_flight = 0, results = 0;
    bool ready = false, queued = false;
    double free_at = 0;  // when its queue of tasks is expected to drain
    std::vector<uint32_t> tasks;
  };
  // The expected finish of a task's best live attempt, for picking stragglers.
  struct Expected {
    double finish = 0;  // +inf: overdue beyond doubt
    double start = 0, duration = 0;
  };

  const TaskRecord* choose(uint32_t serial, WorkerState& w, double now, bool& backup);
  const TaskRecord* choose_adaptive(uint32_t serial, WorkerState& w, double now, bool& backup);
  const TaskRecord* choose_backup(uint32_t serial, WorkerState& w, double now);
  void hand_out(WorkerState& w, const TaskRecord& t, double now);
  void forget_task(WorkerState& w, uint32_t task);
  void learn(WorkerState& w, const TaskRecord& t, double busy_s);
  void rebuild_order();
  double cost_of(int y0, int y1) const;
  double cost_of(const TaskRecord& t) const;  // its rows, or its share of a span's row
  const TaskRecord* cut_row_or_span(uint32_t serial, WorkerState& w, int y, double target, double now);
  void set_expected(uint32_t task, const Expected& e);
  void refresh_overdue(double now);
  void enqueue(uint32_t serial, WorkerState& w);
  bool may_queue_more(const WorkerState& w, double now) const;
  bool estimates_trusted() const;

  PolicyOptions o_;
  TaskBoard& board_;
  std::unordered_map<uint32_t, WorkerState> workers_;
  std::deque<uint32_t> queue_;  // workers with free credit, longest idle first
  size_t fresh_ahead_ = 0;      // leading entries of queue_ that have had no task yet
  void pop_front();
  double total_speed_ = 0;      // of registered workers
  int ready_count_ = 0;
  // adaptive: costs, order, expectations
  std::vector<double> cost_;     // per row, seconds on a speed-1 worker (estimate)
  std::vector<uint8_t> known_;   // per row: cost measured
  std::map<int, double> span_cost_;  // rows cut into spans: speed-1 seconds of their accepted spans so far
  std::vector<int> order_;       // fresh rows, dearest first
  size_t cursor_ = 0;
  size_t grid_end_ = 0;  // order_[0, grid_end_) are rows of the coarse grid
  int known_rows_ = 0, known_at_rebuild_ = 0;
  bool scaled_ = false;          // cost_ is in seconds (a result or a prior came in)
  double fresh_cost_ = 0;        // sum of cost_ over fresh rows
  // How well estimates predicted results: sum |observed - estimated| and sum
  // observed, over tasks of rows that were estimated from measured neighbours.
  double miss_ = 0, observed_ = 0;
  int judged_ = 0;
  bool cost_order_ = false;      // order_ is by cost (trusted estimates), else by row
  std::set<std::pair<double, uint32_t>> stragglers_;  // (expected finish, task)
  std::unordered_map<uint32_t, Expected> expected_;   // by task, live tasks only
  int backups_ = 0;
};

}  // namespace rayfarm
