// Dispatch policies; see dispatch_policy.h.
#include "broker/dispatch_policy.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstring>
#include <limits>
#include <numeric>

#include "broker/row_order.h"
#include "tracer/error.h"

namespace rayfarm {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
// Factoring (Hummel, Schonberg and Flynn, CACM 1992): each task takes
// 1/(kFactor x workers) of the work not yet handed out, so tasks shrink
// geometrically toward the end while early ones stay large and cheap to send.
constexpr double kFactor = 4.0;
// A measured speed replaces the declared one only when it differs by more than
// this: declared weights are steadier than a few noisy early results.
constexpr double kSpeedTolerance = 0.5;
// A task still running after this many times its expected duration is
// presumed lost to a stalled or very slow worker (backups then need no proof).
constexpr double kOverdueFactor = 2.0;
constexpr int kMaxLiveAttempts = 3;
constexpr int kBackupCandidates = 4;
constexpr int kRebuildFraction = 8;
// Estimates order the rows only when they predicted results within this
// (mean relative error); a profile that interpolation mispredicts is better
// served in row order with small tasks.
constexpr double kTrustedError = 0.25;
constexpr int kTrustAfterResults = 16;
// Credit hides latency; it is not worth queueing a task behind more than this
// much expected work (plus four latencies): at the end of a job, a task queued
// on a busy worker waits while others idle.
constexpr double kQueueAheadS = 0.05;
constexpr int kSpeedMinResults = 4;
constexpr int kGridStride = 16;  // the adaptive policy's coarse grid: every 16th row
// The tail: a row is cut into pixel spans once it would keep its worker busy
// longer than 1/kSpanFactor of the time the whole farm needs for the work not
// yet handed out (so the last tasks end within about that of each other).
// In the replay of the paper's lab, 1 leaves Gears 1.6% above the lower
// bound, 2 and 4 every scene within 0.5%, 4 with 1.6x the tasks of 2
// (docs/replay.md).
constexpr double kSpanFactor = 2.0;

bool holds_live(const TaskRecord& t, uint32_t worker) {
  for (const TaskAttempt& a : t.attempts)
    if (a.worker == worker && std::strcmp(a.outcome, "in_flight") == 0) return true;
  return false;
}

}  // namespace

const char* policy_name(PolicyKind kind) {
  switch (kind) {
    case PolicyKind::paper: return "paper";
    case PolicyKind::weighted: return "weighted";
    case PolicyKind::adaptive: return "adaptive";
  }
  return "?";
}

PolicyKind parse_policy(const std::string& name, const std::string& where) {
  for (PolicyKind k : {PolicyKind::paper, PolicyKind::weighted, PolicyKind::adaptive})
    if (name == policy_name(k)) return k;
  throw InputError(where + ": unknown dispatch policy \"" + name + "\" (expected one of: " + kPolicyNames + ")");
}

int weighted_task_rows(double weight, double reference_weight, int base_task_rows) {
  const double rows = std::round(weight / reference_weight * base_task_rows);
  return static_cast<int>(std::clamp(rows, 1.0, 65536.0));
}

int nominal_task_rows(const PolicyOptions& o, double weight) {
  switch (o.kind) {
    case PolicyKind::paper: return o.base_task_rows;
    case PolicyKind::weighted: return weighted_task_rows(weight, o.reference_weight, o.base_task_rows);
    case PolicyKind::adaptive: return 0;
  }
  return 0;
}

DispatchPolicy::DispatchPolicy(PolicyOptions options, TaskBoard& board) : o_(std::move(options)), board_(board) {
  const size_t h = static_cast<size_t>(board.height());
  cost_.assign(h, 1.0);
  known_.assign(h, 0);
  if (o_.kind != PolicyKind::adaptive) return;
  if (o_.prior_costs.size() == h) {
    cost_ = o_.prior_costs;
    scaled_ = true;
    rebuild_order();
  } else {
    // Rows 0, H/2, H/4, 3H/4, ... (bit reversal): the first wave samples the
    // whole image, so costs can be interpolated early (and a preview is whole).
    order_ = coarse_to_fine(board.height(), 1);
    fresh_cost_ = static_cast<double>(h);
  }
}

void DispatchPolicy::add_worker(uint32_t serial, const std::string& name, double weight, int credit) {
  WorkerState w;
  w.name = name;
  w.declared = w.speed = std::max(weight, 1e-9) / o_.reference_weight;
  w.credit = o_.kind == PolicyKind::paper ? 1 : std::max(1, credit);
  total_speed_ += w.speed;
  workers_[serial] = std::move(w);
}

void DispatchPolicy::enqueue(uint32_t serial, WorkerState& w) {
  if (w.queued || !w.ready || w.in_flight >= w.credit) return;
  w.queued = true;
  queue_.push_back(serial);
}

void DispatchPolicy::pop_front() {
  queue_.pop_front();
  if (fresh_ahead_ > 0) --fresh_ahead_;
}

void DispatchPolicy::worker_ready(uint32_t serial, double now) {
  auto it = workers_.find(serial);
  if (it == workers_.end() || it->second.ready) return;
  it->second.ready = true;
  it->second.free_at = now;
  ++ready_count_;
  WorkerState& w = it->second;
  if (w.queued || w.in_flight >= w.credit) return;
  // Ahead of the workers waiting for a second task: the static start gives
  // every ready worker its first task before anyone gets another, even when
  // its job_ready and another's result arrive in the same turn of the loop.
  w.queued = true;
  queue_.insert(queue_.begin() + static_cast<std::ptrdiff_t>(fresh_ahead_), serial);  // in order of readiness
  ++fresh_ahead_;
}

int DispatchPolicy::remove_worker(uint32_t serial, double now) {
  auto it = workers_.find(serial);
  if (it == workers_.end()) return 0;
  WorkerState& w = it->second;
  for (uint32_t task : w.tasks) {
    board_.requeue(task, serial, now);
    if (board_.task(task).live == 0) set_expected(task, Expected{-1, 0, 0});
  }
  const int lost = static_cast<int>(w.tasks.size());
  total_speed_ -= w.speed;
  if (w.ready) --ready_count_;
  workers_.erase(it);  // a stale queue entry is skipped in dispatch()
  return lost;
}

void DispatchPolicy::forget_task(WorkerState& w, uint32_t task) {
  w.tasks.erase(std::find(w.tasks.begin(), w.tasks.end(), task));
  w.in_flight -= 1;
}

Verdict DispatchPolicy::on_result(uint32_t serial, uint32_t task, uint32_t attempt, const PixelBand& band, double now,
                                  double render_s, double throttle_s) {
  const Verdict v = board_.accept(serial, task, attempt, band, now, render_s, throttle_s);
  auto it = workers_.find(serial);
  if (it == workers_.end()) return v;
  WorkerState& w = it->second;
  if (std::find(w.tasks.begin(), w.tasks.end(), task) == w.tasks.end()) return v;  // not one it holds
  if (v == Verdict::mismatch) board_.requeue(task, serial, now);
  if (v == Verdict::accepted) learn(w, board_.task(task), render_s + throttle_s);
  if (board_.task(task).live == 0) set_expected(task, Expected{-1, 0, 0});
  forget_task(w, task);
  if (w.in_flight == 0) w.free_at = now;
  enqueue(serial, w);
  return v;
}

void DispatchPolicy::reject_result(uint32_t serial, uint32_t task, double now) {
  auto it = workers_.find(serial);
  if (it == workers_.end()) return;
  WorkerState& w = it->second;
  if (std::find(w.tasks.begin(), w.tasks.end(), task) == w.tasks.end()) return;
  board_.requeue(task, serial, now);
  if (board_.task(task).live == 0) set_expected(task, Expected{-1, 0, 0});
  forget_task(w, task);
  enqueue(serial, w);
}

// Speed: the learned cost of the rows it rendered over its busy seconds.
// Costs: busy seconds x speed, spread evenly over the task's rows; a row cut
// into spans costs the sum of its spans, known once the last is in (a span's
// share of its row is not a row cost: the pixels of a row differ).
void DispatchPolicy::learn(WorkerState& w, const TaskRecord& t, double busy_s) {
  if (!(busy_s > 0)) return;
  if (scaled_) {
    const double estimate = cost_of(t);
    w.measured_cost += estimate;
    w.measured_busy += busy_s;
    miss_ += std::fabs(busy_s * w.speed - estimate);
    observed_ += busy_s * w.speed;
    ++judged_;
  }
  if (++w.results >= kSpeedMinResults && w.measured_busy > 0) {
    const double measured = w.measured_cost / w.measured_busy;
    const double speed = std::fabs(measured / w.declared - 1) > kSpeedTolerance ? measured : w.declared;
    total_speed_ += speed - w.speed;
    w.speed = speed;
  }
  if (o_.kind != PolicyKind::adaptive) return;
  const auto measured = [&](int y, double cost) {
    known_rows_ += !known_[static_cast<size_t>(y)];
    known_[static_cast<size_t>(y)] = 1;
    cost_[static_cast<size_t>(y)] = cost;
  };
  if (t.span) {
    double& row = span_cost_[t.y0];
    row += busy_s * w.speed;
    if (board_.pixels_done(t.y0) < board_.width()) return;
    measured(t.y0, row);  // the sum of its spans: the next frame's cost of the row
    span_cost_.erase(t.y0);
  } else {
    for (int y = t.y0; y < t.y1; ++y) measured(y, busy_s * w.speed / t.rows());
  }
  scaled_ = true;
  if (known_rows_ >= known_at_rebuild_ + std::max(1, known_at_rebuild_ / kRebuildFraction)) rebuild_order();
}

// Unknown rows take the dearer of the nearest measured rows above and below
// (an underestimated row left to the end of the job is what costs most)
// (a prior frame's costs stand unless measured); fresh rows are re-sorted,
// dearest first. Runs when the measured rows grew by 1/kRebuildFraction:
// O(H log H) about kRebuildFraction x ln H times per job.
void DispatchPolicy::rebuild_order() {
  const int h = board_.height();
  known_at_rebuild_ = std::max(1, known_rows_);
  if (o_.prior_costs.empty() && known_rows_ > 0) {
    int prev = -1;
    auto fill = [&](int a, int b) {  // rows strictly between known rows a and b
      for (int y = a + 1; y < b; ++y) {
        if (a < 0) cost_[static_cast<size_t>(y)] = cost_[static_cast<size_t>(b)];
        else if (b >= h) cost_[static_cast<size_t>(y)] = cost_[static_cast<size_t>(a)];
        else cost_[static_cast<size_t>(y)] = std::max(cost_[static_cast<size_t>(a)], cost_[static_cast<size_t>(b)]);
      }
    };
    for (int y = 0; y < h; ++y)
      if (known_[static_cast<size_t>(y)]) fill(prev, y), prev = y;
    fill(prev, h);
  }
  // A coarse grid (every 16th row, coarse to fine: broker/row_order.h) stays
  // first whatever the estimates say, one row per task: a preview covers the
  // frame after 1/16 of the rows and costs are sampled over all of it. The
  // other rows go dearest first once the estimates are trusted, else top to
  // bottom. In the replay of the paper's lab it moves the makespan by -0.3%
  // (costs learned in the frame) and +0.6% (the previous frame's) on average
  // over the paper's scenes (docs/status-page.md).
  order_.clear();
  fresh_cost_ = 0;
  size_t grid = 0;
  // The open span row's pixels not yet handed out are fresh work too.
  if (const auto open = board_.open_span())
    fresh_cost_ += cost_[static_cast<size_t>(open->first)] * (board_.width() - open->second) / board_.width();
  for (int y : coarse_to_fine(h, kGridStride)) {
    if (!board_.is_fresh(y)) continue;
    order_.push_back(y);
    fresh_cost_ += cost_[static_cast<size_t>(y)];
    grid += y % kGridStride == 0;
  }
  cost_order_ = estimates_trusted();
  if (cost_order_)
    std::stable_sort(order_.begin() + static_cast<std::ptrdiff_t>(grid), order_.end(),
                     [&](int a, int b) { return cost_[static_cast<size_t>(a)] > cost_[static_cast<size_t>(b)]; });
  cursor_ = 0;
  grid_end_ = grid;
}

bool DispatchPolicy::estimates_trusted() const {
  if (!o_.prior_costs.empty()) return true;
  return judged_ >= kTrustAfterResults && miss_ <= kTrustedError * observed_;
}

bool DispatchPolicy::may_queue_more(const WorkerState& w, double now) const {
  if (o_.kind != PolicyKind::adaptive || w.in_flight == 0 || !scaled_) return true;
  return w.free_at - now < kQueueAheadS + 4 * o_.latency_s;
}

double DispatchPolicy::cost_of(int y0, int y1) const {
  return std::accumulate(cost_.begin() + y0, cost_.begin() + y1, 0.0);
}

// A span's share of its row, by pixel count: where in a row the cost lies is
// not measured (a row is the unit costs are learned in).
double DispatchPolicy::cost_of(const TaskRecord& t) const {
  const double rows = cost_of(t.y0, t.y1);
  return t.span ? rows * (t.x1 - t.x0) / board_.width() : rows;
}

void DispatchPolicy::set_expected(uint32_t task, const Expected& e) {
  auto it = expected_.find(task);
  if (it != expected_.end()) stragglers_.erase({it->second.finish, task});
  if (e.finish < 0) {
    if (it != expected_.end()) expected_.erase(it);
    return;
  }
  expected_[task] = e;
  stragglers_.insert({e.finish, task});
}

// Expected finishes that have passed: first allow the task its duration
// again, then presume it lost (finish = +inf). Each task moves at most twice.
void DispatchPolicy::refresh_overdue(double now) {
  while (!stragglers_.empty() && stragglers_.begin()->first < now) {
    const uint32_t task = stragglers_.begin()->second;
    Expected e = expected_.at(task);
    const double deadline = e.start + kOverdueFactor * e.duration + 4 * o_.latency_s;
    e.finish = deadline > now ? deadline : kInf;
    set_expected(task, e);
  }
}

const TaskRecord* DispatchPolicy::choose(uint32_t serial, WorkerState& w, double now, bool& backup) {
  switch (o_.kind) {
    case PolicyKind::paper:
    case PolicyKind::weighted:
      return board_.next(serial, w.name, nominal_task_rows(o_, w.declared * o_.reference_weight), now);
    case PolicyKind::adaptive:
      return choose_adaptive(serial, w, now, backup);
  }
  return nullptr;
}

// Requeued work first, then the rest of a row being cut into spans, then the
// dearest fresh row, grown over fresh neighbours up to the worker's factoring
// share (or, at the tail, cut into spans); then backups.
const TaskRecord* DispatchPolicy::choose_adaptive(uint32_t serial, WorkerState& w, double now, bool& backup) {
  if (const TaskRecord* t = board_.reissue(serial, w.name, now)) return t;
  // Divided by credit: a worker holds that many tasks at once.
  // Until a first wave has sampled about one row per worker, tasks are
  // single rows: an unmeasured band could be the dearest of the image.
  // The grid's rows go out alone, so they stay spread over the frame.
  const bool sampled = known_rows_ >= static_cast<int>(workers_.size()) || !o_.prior_costs.empty();
  const auto share = [&] { return fresh_cost_ * w.speed / (kFactor * w.credit * std::max(total_speed_, w.speed)); };
  const auto span_share = [&] { return fresh_cost_ * w.speed / (kSpanFactor * std::max(total_speed_, w.speed)); };
  if (const auto open = board_.open_span()) return cut_row_or_span(serial, w, open->first, span_share(), now);
  while (cursor_ < order_.size() && !board_.is_fresh(order_[cursor_])) ++cursor_;
  if (cursor_ < order_.size()) {
    const int h = board_.height();
    const int y = order_[cursor_];
    const double target = !sampled || cursor_ < grid_end_ ? 0 : share();
    if (target > 0 && cost_[static_cast<size_t>(y)] > span_share()) return cut_row_or_span(serial, w, y, span_share(), now);
    int y0 = y, y1 = y + 1;
    double c = cost_[static_cast<size_t>(y)];
    const auto room = [&] { return y1 - y0 < o_.max_task_rows; };
    while (room() && y1 < h && board_.is_fresh(y1) && c + cost_[static_cast<size_t>(y1)] <= target) c += cost_[static_cast<size_t>(y1++)];
    while (room() && y0 > 0 && board_.is_fresh(y0 - 1) && c + cost_[static_cast<size_t>(y0 - 1)] <= target) c += cost_[static_cast<size_t>(--y0)];
    fresh_cost_ -= c;
    return board_.cut(serial, w.name, y0, y1, now);
  }
  backup = true;
  return choose_backup(serial, w, now);
}

// The tail of the job: a row dearer than `target` (speed-1 seconds, see
// kSpanFactor) goes out in spans of about that cost, so the last tasks
// end together instead of on the row a slow machine drew. Spans are no
// narrower than min_span_pixels (each is a message and a result), and a
// remainder narrower than that joins the span before it.
const TaskRecord* DispatchPolicy::cut_row_or_span(uint32_t serial, WorkerState& w, int y, double target, double now) {
  const int width = board_.width();
  const auto open = board_.open_span();
  const int x0 = open && open->first == y ? open->second : 0;
  const double row = cost_[static_cast<size_t>(y)];
  const int min_px = o_.min_span_pixels;
  int x1 = width;
  if (min_px > 0 && width >= 2 * min_px && row > target) {
    const int px = std::max(min_px, static_cast<int>(std::ceil(width * target / row)));
    if (width - (x0 + px) >= min_px) x1 = x0 + px;
  }
  fresh_cost_ -= row * (x1 - x0) / width;
  if (x0 == 0 && x1 == width) return board_.cut(serial, w.name, y, y + 1, now);
  return board_.cut_span(serial, w.name, y, x0, x1, now);
}

// The latest-finishing live tasks, if this worker would beat them.
const TaskRecord* DispatchPolicy::choose_backup(uint32_t serial, WorkerState& w, double now) {
  if (board_.has_requeued()) return nullptr;
  refresh_overdue(now);
  int tries = 0;
  for (auto it = stragglers_.rbegin(); it != stragglers_.rend() && tries < kBackupCandidates; ++it, ++tries) {
    const TaskRecord& t = board_.task(it->second);
    if (t.done || t.live == 0 || t.live >= kMaxLiveAttempts || holds_live(t, serial)) continue;
    const double start = std::max(now + o_.latency_s, w.free_at);
    const double finish = start + cost_of(t) / w.speed + o_.latency_s;
    if (finish < it->first) {
      ++backups_;
      return &board_.backup(t.id, serial, w.name, now);
    }
  }
  return nullptr;
}

void DispatchPolicy::hand_out(WorkerState& w, const TaskRecord& t, double now) {
  w.in_flight += 1;
  w.tasks.push_back(t.id);
  if (o_.kind != PolicyKind::adaptive) return;
  Expected e;
  e.duration = cost_of(t) / w.speed;
  e.start = std::max(now + o_.latency_s, w.free_at);
  w.free_at = e.start + e.duration;
  e.finish = w.free_at + o_.latency_s;
  auto it = expected_.find(t.id);
  if (it == expected_.end() || e.finish < it->second.finish) set_expected(t.id, e);
}

void DispatchPolicy::dispatch(double now, std::vector<Dispatch>& out) {
  while (!queue_.empty()) {
    const uint32_t serial = queue_.front();
    auto it = workers_.find(serial);
    if (it == workers_.end()) {
      pop_front();
      continue;
    }
    WorkerState& w = it->second;
    bool backup = false;
    const bool room = w.in_flight < w.credit && may_queue_more(w, now);
    const TaskRecord* t = room ? choose(serial, w, now, backup) : nullptr;
    if (!t && room) break;  // no work for the longest-idle worker: it stays first
    pop_front();
    w.queued = false;
    if (!t) continue;
    hand_out(w, *t, now);
    out.push_back(Dispatch{serial, t->id, t->attempt(), t->y0, t->y1, t->x0, t->x1, backup});
    enqueue(serial, w);  // round robin: its next task after everyone else's
  }
  if (o_.kind != PolicyKind::adaptive || queue_.empty() || !board_.all_handed_out() || board_.has_requeued()) return;
  // The end of the job: every idle worker may back up a straggler it would beat.
  std::deque<uint32_t> still_idle;
  for (uint32_t serial : queue_) {
    auto it = workers_.find(serial);
    if (it == workers_.end()) continue;
    WorkerState& w = it->second;
    const TaskRecord* t = w.in_flight < w.credit && may_queue_more(w, now) ? choose_backup(serial, w, now) : nullptr;
    if (t) {
      hand_out(w, *t, now);
      out.push_back(Dispatch{serial, t->id, t->attempt(), t->y0, t->y1, t->x0, t->x1, true});
    }
    if (w.in_flight < w.credit)
      still_idle.push_back(serial);
    else
      w.queued = false;
  }
  queue_.swap(still_idle);
  fresh_ahead_ = 0;
}

int DispatchPolicy::in_flight(uint32_t serial) const {
  auto it = workers_.find(serial);
  return it == workers_.end() ? 0 : it->second.in_flight;
}

double DispatchPolicy::speed_of(uint32_t serial) const {
  auto it = workers_.find(serial);
  return it == workers_.end() ? 0 : it->second.speed;
}

}  // namespace rayfarm
