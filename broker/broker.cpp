// The farm broker; see broker.h and protocol/SPEC.md for the rules it enforces.
#include "broker/broker.h"

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <fstream>
#include <optional>
#include <random>
#include <set>
#include <stdexcept>
#include <unordered_map>

#include "broker/admission.h"
#include "broker/dispatch_policy.h"
#include "broker/handshake_failures.h"
#include "broker/job_record.h"
#include "broker/progress.h"
#include "broker/task_board.h"
#include "protocol/transport.h"
#include "tracer/error.h"
#include "tracer/image_memory.h"
#include "tracer/log_text.h"

namespace rayfarm {
namespace {

using Clock = std::chrono::steady_clock;
using namespace protocol;

constexpr auto kSweepPeriod = std::chrono::milliseconds(10);  // heartbeat and expiry checks
constexpr int kUnusableResultsAllowed = 3;  // per worker and job (Broker::count_unusable)

// Whether `port` is one the kernel hands out as the local port of outgoing
// connections (/proc/sys/net/ipv4/ip_local_port_range); its range in `range`.
bool is_ephemeral_port(int port, std::string& range) {
  std::ifstream in("/proc/sys/net/ipv4/ip_local_port_range");
  int low = 0, high = 0;
  if (!(in >> low >> high)) return false;
  range = std::to_string(low) + "-" + std::to_string(high);
  return port >= low && port <= high;
}

double since(Clock::time_point t0, Clock::time_point t) { return std::chrono::duration<double>(t - t0).count(); }

// A registered worker connection.
struct LiveWorker {
  std::string identity;
  std::string key;  // CURVE public key (Z85) of the connection that registered; "" without keys
  uint32_t serial = 0;
  Ready info;
  int task_rows = 1;
  uint64_t loaded_job = 0;
  // Announced-early jobs this worker has loaded: when, and its init time.
  std::map<uint64_t, std::pair<Clock::time_point, double>> preloaded;
  std::map<uint64_t, JobFailed> prefailed;  // the early-announced job failed to load here
  Clock::time_point expiry, last_sent, last_heard;
  // The job whose scene this worker was last sent on a fetch, and when.
  uint64_t fetched_job = 0;
  Clock::time_point fetched_at;
};

// The job being rendered.
struct ActiveJob {
  JobSpec spec;
  Frames announcement;  // encoded `job` message, reused for every fetch
  TaskBoard board;
  DispatchPolicy policy;  // decides over `board`
  std::vector<Dispatch> dispatched;  // reused by every dispatch()
  std::vector<float> rgb;
  RayStats stats;
  Clock::time_point t0;
  double first_ready = -1, first_dispatch = -1, last_result = 0;
  std::vector<WorkerRecord> records;
  std::map<uint32_t, size_t> record_of;  // serial -> index in records
  // Registrations (serials) that reported job_failed. Not names: two machines
  // may share a name, and a worker reports a job once (it never loads a failed
  // job again, re-registered or not), so each serial is one worker.
  std::set<uint32_t> failed_by;
  // Results a worker sent that could not be used (corrupt or mismatched),
  // by serial; at kUnusableResultsAllowed it is given no more of the job.
  std::map<uint32_t, int> unusable_results;
  std::set<uint32_t> excluded;
  std::optional<std::string> failure;    // set: the job has failed for this reason
  std::map<uint32_t, Clock::time_point> gone_at;  // serial -> when it was dropped
  std::set<uint32_t> handed_tasks;  // serials dispatched to at least once
  // Registrations that ended before being handed a task: counted, not kept.
  // A peer may send `ready` as often as it likes, each a new registration.
  int registrations_without_tasks = 0;
  std::map<int, RayStats> span_stats;  // rows being rendered in spans: the rays of their spans so far
  FarmHooks hooks;

  ActiveJob(const JobSpec& s, const FarmJob& in, FarmHooks h, PolicyOptions policy_options)
      : spec(s), announcement(encode(Message{s})), board(s.settings.height, s.settings.width, in.restored_rows),
        policy(std::move(policy_options), board), stats(in.restored_stats), hooks(std::move(h)) {
    if (in.restored_rows.empty())
      rgb.assign(static_cast<size_t>(s.settings.width) * s.settings.height * 3, 0.0f);
    else
      rgb = in.restored_rgb;
  }
  WorkerRecord& record(uint32_t serial) { return records[record_of.at(serial)]; }

  // A registration that ends having been handed no task and having failed
  // nothing left no trace in any task: it leaves the record for the count.
  bool did_no_work(uint32_t serial) const { return !handed_tasks.count(serial) && !failed_by.count(serial); }
  void fold_record(uint32_t serial) {
    const size_t index = record_of.at(serial);
    records.erase(records.begin() + static_cast<std::ptrdiff_t>(index));
    record_of.erase(serial);
    for (auto& [other, i] : record_of)
      if (i > index) --i;
    ++registrations_without_tasks;
  }

  // An accepted span's pixels go into the image at once. Returns the whole
  // row when this span completes it (its pixels from the image, the rays of
  // all its spans): what the hooks journal and the preview shows is rows.
  std::optional<TaskResult> add_span(const TaskResult& r) {
    const size_t row_floats = static_cast<size_t>(r.width) * 3;
    float* row = &rgb[static_cast<size_t>(r.y0) * row_floats];
    std::memcpy(row + static_cast<size_t>(r.x0) * 3, r.rgb.data(), r.rgb.size() * sizeof(float));
    RayStats& rays = span_stats[r.y0];
    rays += r.stats;
    if (board.pixels_done(r.y0) + (r.x1 - r.x0) < r.width) return std::nullopt;
    TaskResult whole = r;
    whole.x0 = 0;
    whole.x1 = r.width;
    whole.stats = rays;
    whole.rgb.assign(row, row + row_floats);
    span_stats.erase(r.y0);
    return whole;
  }
};

std::string describe(const LiveWorker& w) { return worker_id(w.info.name, w.serial); }

// Whether the rows restored after a restart cover the whole image.
bool restored_whole(const FarmJob& job) {
  std::vector<bool> have(static_cast<size_t>(std::max(0, job.settings.height)), false);
  for (const auto& [y0, y1] : job.restored_rows)
    for (int y = std::max(0, y0); y < std::min(y1, job.settings.height); ++y) have[static_cast<size_t>(y)] = true;
  return std::all_of(have.begin(), have.end(), [](bool h) { return h; });
}

}  // namespace

struct Broker::Impl {
  BrokerConfig cfg;
  LogSink log_sink;
  zmq::context_t ctx{1};
  BrokerKeys keys;
  ZapHandler zap;  // bound before either socket, so no handshake goes unchecked
  zmq::socket_t router{ctx, zmq::socket_type::router};
  zmq::socket_t pub{ctx, zmq::socket_type::pub};
  // Every worker's first handshake is on the ROUTER; watched before it binds.
  HandshakeFailures handshakes;
  std::string router_endpoint, pub_endpoint;
  std::map<std::string, LiveWorker> workers;  // by ROUTER identity
  std::unordered_map<uint32_t, LiveWorker*> by_serial;
  std::vector<double> last_row_costs;  // the previous job's, for the next frame's policy
  uint32_t next_serial = 1;
  uint64_t next_job_id = 1;
  std::unique_ptr<ActiveJob> job;
  // The next job, announced while the current one finishes (FarmHooks::upcoming).
  struct Early {
    JobSpec spec;
    Frames announcement;
  };
  std::optional<Early> early;
  bool early_asked = false;
  std::map<std::string, int> rejected;
  // Accepted bands and their round trips since the last watch call (FarmProgress).
  std::vector<std::pair<int, int>> new_bands;
  std::vector<double> new_round_trips;
  ProgressMeter progress;
  // Lines a peer can cause at will are rate-limited, so a flood of garbage or
  // of registrations cannot flood the log, nor one kind of line hide another:
  // a new worker's registration is seen while another connection floods `ready`.
  // New connections' registrations get room for a whole farm starting at once
  // (the paper's lab is 85 machines); a flood of them costs a handshake each.
  struct LogLimit {
    const char* what;  // in "(N more WHAT not shown)"
    int per_second;
    Clock::time_point window{};
    int logged = 0, suppressed = 0;
    size_t requeued = 0;  // tasks requeued by the lines held back: work moved is said even so
  };
  LogLimit rejection_lines{"rejections", 20}, registration_lines{"registrations", 200},
      reregistration_lines{"re-registrations", 20};
  bool shutting_down = false;
  Clock::time_point next_sweep;
  // A broker without workers says so once a liveness period has passed
  // (note_if_alone): keys on one side only fail the handshake, and a worker
  // that raced ahead in it may be the only side that logs why.
  Clock::time_point alone_since = Clock::now();
  int accepted_when_alone = 0;
  int unregistered_when_alone = 0;  // rejected["unknown_worker"] then
  bool told_alone = false;

  Impl(BrokerConfig c, LogSink sink)
      : cfg(std::move(c)), log_sink(std::move(sink)),
        keys(load_broker_keys(cfg.key_file, cfg.allow_dir, cfg.insecure)),
        zap(ctx, keys.policy, [this](const std::string& line) { log(line); }),
        handshakes(ctx, router, keys.own ? keys.own->public_key : "", [this](const std::string& line) { log(line); }),
        progress(cfg.progress, cfg.progress_interval_s) {
    configure_socket(router, max_worker_frame_bytes(cfg));
    configure_socket(pub, protocol::kMaxJsonBytes);  // a PUB only hears subscriptions
    secure_broker_socket(router, keys);
    secure_broker_socket(pub, keys);  // the scene goes out on PUB: invited subscribers only
    router_endpoint = bind(router, cfg.bind, "worker");
    pub_endpoint = bind(pub, cfg.announce_bind, "announce");
    log(admission_banner(keys, router_endpoint));
    std::random_device rd;  // job ids differ between broker runs, so worker caches never confuse them
    next_job_id = ((uint64_t{rd()} << 16) ^ rd()) & ((uint64_t{1} << 44) - 1);
    next_job_id += 1;
  }

  std::string bind(zmq::socket_t& s, const std::string& endpoint, const char* what) const {
    for (const std::string& problem : {protocol::farm_transport_problem(endpoint), protocol::tcp_port_problem(endpoint)})
      if (!problem.empty())
        throw InputError(std::string("cannot bind the ") + what + " socket to '" + endpoint + "': " + problem);
    try {
      s.bind(endpoint);
    } catch (const zmq::error_t& e) {
      throw InputError(std::string("cannot bind the ") + what + " socket to '" + endpoint + "': " + e.what() +
                       (e.num() == EADDRINUSE ? why_in_use(endpoint) : "") +
                       // ZeroMQ reads a bind's host as an interface name when it is no IP address.
                       (e.num() == ENODEV ? " (bind to an IP address, * or an interface name, not a host name)" : ""));
    }
    return s.get(zmq::sockopt::last_endpoint);
  }

  // What may hold a port in use besides another program listening there.
  std::string why_in_use(const std::string& endpoint) const {
    const std::string digits = endpoint.substr(endpoint.rfind(':') + 1);
    if (digits.empty() || digits.find_first_not_of("0123456789") != std::string::npos || digits.size() > 5) return "";
    const int port = std::stoi(digits);
    if (!router_endpoint.empty() && endpoint_port(router_endpoint) == port)
      return ": the worker socket (--bind) is bound to that port already (" + router_endpoint +
             "); give --announce a port of its own";
    // The kernel gives ports of this range to outgoing connections as their
    // own end, held until the connection and its TIME-WAIT are over; a worker
    // retrying a connection to such a port with no broker there can even be
    // given that very port, connect to itself (TCP's simultaneous open) and
    // hold it: the broker restarted there is refused.
    if (std::string range; is_ephemeral_port(port, range))
      return " (" + digits + " is in the kernel's ephemeral port range, " + range +
             ": if no other program listens there, an outgoing connection may hold it as its own end, until it "
             "and its TIME-WAIT are over; a worker retrying its connection may even have connected to itself; "
             "give the broker a port outside that range, docs/deployment.md)";
    return "";
  }

  void log(const std::string& line) {
    progress.clear_line();
    write_log(log_sink, line);
  }

  // At most `per_second` events of a kind are logged a second; the rest are counted
  // and the count said once their second is over. Whether this one is shown.
  bool shown(LogLimit& limit) {
    close_log_window(limit, Clock::now());
    if (++limit.logged <= limit.per_second) return true;
    ++limit.suppressed;
    return false;
  }

  void close_log_window(LogLimit& limit, Clock::time_point now) {
    if (now - limit.window <= std::chrono::seconds(1)) return;
    say_suppressed(limit);
    limit.window = now;
    limit.logged = 0;
  }

  // Said before a job's end, done or failed, not with the next job's lines (or never).
  void say_all_suppressed() {
    for (LogLimit* limit : {&rejection_lines, &registration_lines, &reregistration_lines}) say_suppressed(*limit);
  }

  void say_suppressed(LogLimit& limit) {
    if (limit.suppressed)
      log("(" + std::to_string(limit.suppressed) + " more " + limit.what + " not shown" +
          (limit.requeued ? "; they requeued " + std::to_string(limit.requeued) + " task(s)" : "") + ")");
    limit.suppressed = 0;
    limit.requeued = 0;
  }

  void reject(const std::string& reason, const std::string& detail) {
    ++rejected[reason];
    if (shown(rejection_lines)) log("rejected " + detail);
  }

  void send_to(LiveWorker& w, const Message& m) {
    send(router, m, &w.identity);
    w.last_sent = Clock::now();
  }

  // ---- registration and loss ------------------------------------------------

  // A `ready` always starts a fresh registration with a new serial: results
  // for tasks of an earlier registration of the same socket are then "stale"
  // or "unassigned", never silently accepted.
  void register_worker(const std::string& identity, const std::string& key, const Ready& ready) {
    auto old = workers.find(identity);
    // Both lines of a re-registration are shown, or neither.
    const bool logged = shown(old != workers.end() ? reregistration_lines : registration_lines);
    if (old != workers.end()) drop_worker(old, "left", "re-registered", logged);
    LiveWorker w;
    w.identity = identity;
    w.key = key;
    w.serial = next_serial++;
    w.info = ready;
    w.task_rows = task_rows_for(cfg, ready.weight);
    const auto now = Clock::now();
    w.expiry = now + std::chrono::milliseconds(silence_limit_ms(ready.heartbeat_ms, cfg.liveness));
    w.last_heard = now;
    LiveWorker& live = workers.emplace(identity, std::move(w)).first->second;
    by_serial[live.serial] = &live;
    if (job) add_record(live);
    send_to(live, Welcome{cfg.heartbeat_ms, cfg.liveness, endpoint_port(pub_endpoint), job ? job->spec.job : 0});
    // The name is joined whole: printed into the buffer, a name of 128 bytes
    // (the protocol's limit) cut the line off before its credit and threads.
    char buf[160];
    std::snprintf(buf, sizeof buf, " registered: weight %g (%d rows/task, 0 = sized per task), credit %d, threads %d, throttle %g",
                  ready.weight, live.task_rows, ready.credit, ready.threads, ready.throttle);
    if (logged) log("worker " + describe(live) + buf + (key.empty() ? std::string() : ", key " + zap.name_of(key)));
  }

  void add_record(const LiveWorker& w) {
    WorkerRecord r;
    r.serial = w.serial;
    r.name = w.info.name;
    r.weight = w.info.weight;
    r.threads = w.info.threads;
    r.credit = w.info.credit;
    r.throttle = w.info.throttle;
    r.task_rows = w.task_rows;
    job->record_of[w.serial] = job->records.size();
    job->records.push_back(r);
    job->policy.add_worker(w.serial, w.info.name, w.info.weight, w.info.credit);
  }

  // The worker is gone (silent, said bye, or re-registered): its in-flight
  // tasks go back to the front of the queue with attempt + 1. `logged`:
  // false for a re-registration held back by its rate limit, whose requeued
  // tasks are then said with the count of lines held back.
  void drop_worker(std::map<std::string, LiveWorker>::iterator it, const char* state, const std::string& why,
                   bool logged = true) {
    LiveWorker& w = it->second;
    const size_t requeued = requeue_in_flight(w, state);
    if (job && job->record_of.count(w.serial)) {
      if (job->did_no_work(w.serial))
        job->fold_record(w.serial);
      else
        job->gone_at[w.serial] = Clock::now();
    }
    if (logged)
      log("worker " + describe(w) + " " + why + (requeued ? ", requeued " + std::to_string(requeued) + " task(s)" : ""));
    else
      reregistration_lines.requeued += requeued;
    by_serial.erase(w.serial);
    workers.erase(it);
  }

  // The worker leaves the job's dispatch: its live attempts are requeued and
  // its job record entry gets `state`. Returns how many.
  size_t requeue_in_flight(LiveWorker& w, const char* state) {
    if (!job || !job->record_of.count(w.serial)) return 0;
    const size_t requeued = static_cast<size_t>(job->policy.remove_worker(w.serial, since(job->t0, Clock::now())));
    WorkerRecord& r = job->record(w.serial);
    r.tasks_lost += static_cast<int>(requeued);
    r.state = state;
    return requeued;
  }

  // ---- messages ---------------------------------------------------------------

  // `key`: the connection's CURVE key as the ZAP handler admitted it ("" without keys).
  void handle(const std::string& identity, const std::string& key, const Frames& frames) {
    Message m;
    try {
      m = decode(frames);
    } catch (const ProtocolError& e) {
      auto it = workers.find(identity);
      const auto* content = dynamic_cast<const ResultContentError*>(&e);
      if (content && it != workers.end() && it->second.key == key && requeue_unreadable(it->second, *content)) {
        reject("corrupt", "message from " + describe(it->second) + ": " + e.what() + "; task " +
                              std::to_string(content->task) + " requeued");
        return count_unusable(it->second, e.what());
      }
      reject("malformed", "message from " + (it != workers.end() ? describe(it->second) : std::string("unknown peer")) +
                              ": " + e.what());
      // A worker of another protocol version heard nothing back and said only
      // "no broker answered": an answer it cannot decode makes it log the
      // versions ("rejected message from broker: v: unsupported ...").
      if (std::string(e.what()).rfind("v: ", 0) == 0)
        send(router, Message{Reregister{std::string("refused: ") + e.what()}}, &identity);
      return;
    }
    if (shutting_down) {
      send(router, Message{Shutdown{}}, &identity);
      return;
    }
    auto it = workers.find(identity);
    if (it != workers.end() && it->second.key != key) {
      // A registration belongs to the key that made it: another key reusing its
      // routing id may neither re-register it nor speak for it.
      return reject("wrong_key", std::string("'") + type_name(m) + "' for " + describe(it->second) +
                                     " from a connection with another key");
    }
    if (auto* ready = std::get_if<Ready>(&m)) return register_worker(identity, key, *ready);
    if (it == workers.end()) {
      // Majordomo's rule: a peer we do not know must register before anything else.
      reject("unknown_worker", std::string("'") + type_name(m) + "' from an unregistered peer; told to re-register");
      send(router, Message{Reregister{"unknown worker: send ready"}}, &identity);
      return;
    }
    LiveWorker& w = it->second;
    // Any well-formed message is a sign of life, not only heartbeats (Paranoid Pirate).
    w.last_heard = Clock::now();
    w.expiry = w.last_heard + std::chrono::milliseconds(silence_limit_ms(w.info.heartbeat_ms, cfg.liveness));
    if (std::holds_alternative<Heartbeat>(m)) return;
    if (auto* f = std::get_if<FetchJob>(&m)) return on_fetch(w, *f);
    if (auto* r = std::get_if<JobReady>(&m)) return on_job_ready(w, *r);
    if (auto* r = std::get_if<TaskResult>(&m)) return on_result(w, *r);
    if (auto* f = std::get_if<JobFailed>(&m)) return on_job_failed(w, *f);
    if (std::holds_alternative<Bye>(m)) return drop_worker(it, "left", "said bye");
    reject("unexpected", std::string("'") + type_name(m) + "' from " + describe(w) + ": not a worker-to-broker message");
  }

  void on_fetch(LiveWorker& w, const FetchJob& f) {
    const bool is_early = early && f.job == early->spec.job;
    if (!is_early && (!job || f.job != job->spec.job)) {
      reject("unknown_job", "fetch of job " + std::to_string(f.job) + " from " + describe(w) + ": no such job");
      send_to(w, Heartbeat{job ? job->spec.job : 0});
      return;
    }
    if (refetch_too_soon(w, f.job)) return;
    send(router, is_early ? early->announcement : job->announcement, &w.identity);
    w.last_sent = Clock::now();
  }

  // Each answer to a fetch is a copy of the scene (up to 256 MiB) queued for
  // that worker: a worker sending fetch_job in a loop made the broker queue a
  // copy per fetch, 300 fetches of a 4 MB scene 760 MB of memory. A worker
  // fetches a job again only after a liveness period without it
  // (protocol/SPEC.md, rule 2): sooner than half of one, it is not answered.
  bool refetch_too_soon(LiveWorker& w, uint64_t fetched) {
    const auto now = Clock::now();
    const auto period = std::chrono::milliseconds(int64_t{cfg.heartbeat_ms} * cfg.liveness / 2);
    if (w.fetched_job == fetched && now - w.fetched_at < period) {
      reject("refetch", "fetch of job " + std::to_string(fetched) + " from " + describe(w) + " within " +
                            std::to_string(period.count()) + " ms of the copy sent to it: not sent again");
      return true;
    }
    w.fetched_job = fetched;
    w.fetched_at = now;
    return false;
  }

  void on_job_ready(LiveWorker& w, const JobReady& r) {
    if (early && r.job == early->spec.job) {
      w.preloaded[r.job] = {Clock::now(), r.init_s};
      return;
    }
    if (!job || r.job != job->spec.job) return;  // an old job finished loading: harmless
    if (job->excluded.count(w.serial)) return;    // its results could not be used: no more tasks
    w.loaded_job = r.job;
    const double now = since(job->t0, Clock::now());
    WorkerRecord& rec = job->record(w.serial);
    rec.init_s = r.init_s;
    rec.ready_at = now;
    if (job->first_ready < 0) job->first_ready = now;
    job->policy.worker_ready(w.serial, now);
  }

  // Rule 8 of protocol/SPEC.md: a worker that cannot render the job gets no
  // more of its tasks. The job fails at once when the fault is the job's own,
  // else when a second worker fails it too (one sick machine is not a bad job).
  void on_job_failed(LiveWorker& w, const JobFailed& f) {
    if (early && f.job == early->spec.job) {  // judged when that job starts
      w.prefailed[f.job] = f;
      return;
    }
    if (!job || f.job != job->spec.job) return;
    const size_t requeued = requeue_in_flight(w, "failed");
    w.loaded_job = 0;
    log("worker " + describe(w) + " cannot render job " + std::to_string(f.job) + " (" + scope_name(f.scope) +
        "): " + f.reason + (requeued ? "; requeued " + std::to_string(requeued) + " task(s)" : ""));
    job->failed_by.insert(w.serial);
    if (f.scope == FailureScope::job)
      job->failure = f.reason;
    else if (job->failed_by.size() >= 2)
      job->failure = f.reason + " (and " + std::to_string(job->failed_by.size() - 1) + " other worker(s) failed)";
  }

  // A result that failed decoding after naming its task (non-finite pixels, a
  // wrong length, rows out of range: a worker with bad memory or a broken FPU
  // that still heartbeats). When the sender holds that live attempt, the task
  // is requeued and the worker's credit freed at once, as for a mismatch (rule
  // 4 of protocol/SPEC.md): left held, its rows waited for a backup at the
  // tail, or forever under a policy without backups. Whether it did.
  bool requeue_unreadable(LiveWorker& w, const ResultContentError& e) {
    if (!job || e.job != job->spec.job || !job->board.holds(w.serial, e.task, e.attempt)) return false;
    job->policy.reject_result(w.serial, e.task, since(job->t0, Clock::now()));
    return true;
  }

  // A worker whose results cannot be used (corrupt or mismatched: bad memory,
  // a broken FPU, a bug) had each task it failed handed straight back to it
  // while it was the one with free credit: thousands of attempts a second,
  // and a job record growing without bound. After kUnusableResultsAllowed of
  // them it is given no more of this job's tasks, as a worker that failed the
  // job (rule 8), without failing the job: the fault is the machine's.
  void count_unusable(LiveWorker& w, const std::string& last) {
    if (!job || job->excluded.count(w.serial) || ++job->unusable_results[w.serial] < kUnusableResultsAllowed) return;
    job->excluded.insert(w.serial);
    const size_t requeued = requeue_in_flight(w, "excluded");
    w.loaded_job = 0;
    log("worker " + describe(w) + " sent " + std::to_string(kUnusableResultsAllowed) + " results of job " +
        std::to_string(job->spec.job) + " that could not be used (the last: " + last +
        "): it is given no more of its tasks" + (requeued ? "; requeued " + std::to_string(requeued) + " task(s)" : ""));
  }

  // Rule 4 of protocol/SPEC.md: only a holder of a live attempt may complete
  // a task, once. Rows are copied straight into the image.
  void on_result(LiveWorker& w, const TaskResult& r) {
    auto what = [&] {  // only for rejections: an accepted result builds no strings
      return "result for task " + std::to_string(r.task) + " attempt " + std::to_string(r.attempt) + " from " + describe(w);
    };
    if (!job || r.job != job->spec.job) return reject("unknown_job", what() + ": not the current job");
    const double now = since(job->t0, Clock::now());
    if (r.width != job->spec.settings.width) {
      job->policy.reject_result(w.serial, r.task, now);
      reject("mismatch", what() + ": mismatch");
      return count_unusable(w, "width " + std::to_string(r.width) + ", not the job's");
    }
    // Judged first, journaled by the hook, and only then counted as done.
    // Every verdict goes to the policy: a loser's or a mismatch's credit is
    // freed there (and a mismatched task requeued), not only a winner's.
    // A span's row is journaled whole, when its last span is in: a crash
    // before that renders the row's spans again, and nothing half done is kept.
    const PixelBand band{r.y0, r.y1, r.x0, r.x1};
    const bool span = r.x0 > 0 || r.x1 < r.width;
    bool row_complete = !span;
    if (job->board.judge(w.serial, r.task, r.attempt, band) == Verdict::accepted) {
      const std::optional<TaskResult> row = span ? job->add_span(r) : std::nullopt;
      row_complete = !span || row.has_value();
      if (job->hooks.accepted && row_complete) job->hooks.accepted(span ? *row : r);
    }
    const Verdict v = job->policy.on_result(w.serial, r.task, r.attempt, band, now, r.render_s, r.throttle_s);
    if (v == Verdict::beaten) return;  // a backup race's loser: expected, not a rejection
    if (v != Verdict::accepted) {
      reject(verdict_name(v), what() + ": " + verdict_name(v));
      if (v == Verdict::mismatch) count_unusable(w, "rows or pixels not the task's");
      return;
    }
    const size_t row_floats = static_cast<size_t>(r.width) * 3;
    if (!span) std::memcpy(&job->rgb[static_cast<size_t>(r.y0) * row_floats], r.rgb.data(), r.rgb.size() * sizeof(float));
    job->stats += r.stats;
    job->last_result = now;
    if (row_complete) new_bands.emplace_back(r.y0, r.y1);
    new_round_trips.push_back(now - job->board.task(r.task).attempts[r.attempt - 1].dispatched);
    WorkerRecord& rec = job->record(w.serial);
    rec.tasks += 1;
    rec.spans += span;
    rec.rows += row_complete ? r.y1 - r.y0 : 0;  // a row in spans counts for whoever completed it
    rec.render_s += r.render_s;
    rec.throttle_s += r.throttle_s;
    rec.busy_s += r.render_s + r.throttle_s;
  }

  // ---- periodic work ----------------------------------------------------------

  // One turn of the loop: wait up to `timeout_ms` for messages, handle them,
  // then heartbeat idle links, expire silent workers and hand out work.
  void turn(int timeout_ms) {
    zmq::pollitem_t items[] = {{router.handle(), 0, ZMQ_POLLIN, 0},
                               {zap.socket().handle(), 0, ZMQ_POLLIN, 0},
                               {handshakes.socket().handle(), 0, ZMQ_POLLIN, 0}};
    poll_interruptible(items, 3, timeout_ms);
    zap.serve_pending();
    handshakes.serve_pending();
    std::string identity, key;
    for (int i = 0; i < 10000; ++i) {  // bounded so timers still run under a flood
      auto frames = receive(router, &identity, &key);
      if (!frames) break;
      handle(identity, key, *frames);
    }
    if (job) dispatch();
    // A quarter of the image is the window a load has to hide in: long enough
    // for a BVH build on most jobs, short enough that two scenes are resident
    // on the workers only for the tail of each job.
    if (job && !early_asked && job->hooks.upcoming && job->board.rows_waiting() <= job->board.height() / 4)
      announce_early();
    const auto now = Clock::now();
    if (now < next_sweep) return;
    // The sweep is O(workers): at most every kSweepPeriod, not every turn, so
    // a busy broker's cost per message does not grow with the farm.
    next_sweep = now + kSweepPeriod;
    // A flood that stopped still has its count said.
    close_log_window(rejection_lines, now);
    close_log_window(registration_lines, now);
    close_log_window(reregistration_lines, now);
    // Heartbeat only links that were quiet for an interval: a busy link's
    // tasks and replies already prove the broker alive.
    for (auto it = workers.begin(); it != workers.end();) {
      auto next = std::next(it);
      LiveWorker& w = it->second;
      if (now > w.expiry) {
        const int64_t silence_ms = silence_limit_ms(w.info.heartbeat_ms, cfg.liveness);
        drop_worker(it, "lost", "silent for " + std::to_string(silence_ms) + " ms: lost");
      } else if (now - w.last_sent >= std::chrono::milliseconds(cfg.heartbeat_ms)) {
        send_to(w, Heartbeat{job ? job->spec.job : 0});
      }
      it = next;
    }
  }

  // A job waits on a broker that no worker has registered with for a
  // liveness period: says once (per such stretch) what reached it -- nothing,
  // messages from peers it does not know (a lost worker back on its old
  // connection), connections that never registered (keys) -- and what follows.
  void note_if_alone() {
    const auto now = Clock::now();
    if (!workers.empty()) {
      alone_since = now;
      accepted_when_alone = handshakes.accepted();
      unregistered_when_alone = rejected["unknown_worker"];
      told_alone = false;
      return;
    }
    const int period_ms = cfg.heartbeat_ms * cfg.liveness;
    if (told_alone || now - alone_since < std::chrono::milliseconds(period_ms)) return;
    told_alone = true;
    log(alone_message(period_ms));
  }

  std::string alone_message(int period_ms) {
    const std::string silence = "still no worker after " + std::to_string(period_ms) + " ms";
    const int unregistered = rejected["unknown_worker"] - unregistered_when_alone;
    const int connections = handshakes.accepted() - accepted_when_alone;
    const int open = handshakes.open_connections();
    // Said "none connected" while a paused worker's connection was still open
    // and its heartbeats were being rejected as from an unregistered peer.
    if (unregistered > 0)
      return silence + ", though " + std::to_string(unregistered) +
             " message(s) came from unregistered peers (a lost worker back on its old connection, e.g. resumed "
             "after a pause): each was told to re-register, and registers again with its next 'ready'";
    if (connections == 0 && open > 0)
      return silence + "; " + std::to_string(open) + " connection(s) to " + router_endpoint +
             " are still open but silent (a lost worker paused or stalled keeps its connection; it re-registers "
             "when it resumes)";
    if (connections == 0)
      return silence + ", and none connected to " + router_endpoint +
             ": are the workers started, with --connect naming this host and port?";
    return silence + ", though " + std::to_string(connections) + " connection(s) reached " + router_endpoint +
           ": a worker whose keys do not match this broker's fails in the handshake, where only the worker may log "
           "why (see its log). " + key_advice();
  }

  std::string key_advice() const {
    if (keys.own)
      return "This broker runs with CURVE keys: a worker needs --key (its .pub in the --allow folder) and "
             "--broker-key holding this broker's public key " + keys.own->public_key;
    return "This broker runs without keys: a worker must have neither --key nor --broker-key";
  }

  // The job's tail has begun: announce what comes next, so workers load it
  // now instead of after the image is assembled.
  void announce_early() {
    early_asked = true;
    std::optional<FarmJob> next = job->hooks.upcoming();
    if (!next) return;
    JobSpec spec = spec_of(*next);
    early = Early{spec, encode(Message{spec})};
    send(pub, early->announcement);
    log("job " + std::to_string(spec.job) + ": " + spec.scene_name + " announced early, while job " +
        std::to_string(job->spec.job) + " finishes");
  }

  JobSpec spec_of(const FarmJob& in) {
    JobSpec spec;
    spec.job = next_job_id++;
    spec.scene_text = in.scene_text;
    spec.scene_hash = fnv1a64(in.scene_text);
    // A one-shot job is named by its path, which may be in Latin-1: sent as
    // is, the job message could not be encoded, and the broker died with a
    // JSON library error as its first worker registered.
    spec.scene_name = valid_utf8(in.scene_name);
    spec.settings = in.settings;
    return spec;
  }

  // The early announcement stands for `in` if it names the same scene and settings.
  bool early_matches(const FarmJob& in) const {
    if (!early) return false;
    const JobSpec& e = early->spec;
    return e.scene_name == valid_utf8(in.scene_name) && e.scene_text == in.scene_text && same_pixels(e.settings, in.settings);
  }

  // Demand-driven dispatch with credit; broker/dispatch_policy.h decides.
  void dispatch() {
    job->dispatched.clear();
    const double now = since(job->t0, Clock::now());
    job->policy.dispatch(now, job->dispatched);
    for (const Dispatch& d : job->dispatched) {
      if (job->hooks.sent) job->hooks.sent(PixelBand{d.y0, d.y1, d.x0, d.x1});
      send_to(*by_serial.at(d.worker), TaskAssign{job->spec.job, d.task, d.attempt, d.y0, d.y1, d.x0, d.x1});
      job->handed_tasks.insert(d.worker);
      if (job->first_dispatch < 0) job->first_dispatch = now;
    }
  }

  FarmProgress snapshot() const {
    FarmProgress p;
    p.workers = static_cast<int>(workers.size());
    p.rejected = rejected;
    p.worker_views = worker_views();
    if (job) {
      p.job = job->spec.job;
      p.rows_done = job->board.rows_done();
      p.rows_total = job->board.height();
      for (const WorkerRecord& r : job->records) p.tasks_done[worker_id(r.name, r.serial)] = r.tasks;
      p.new_bands = new_bands;
      p.new_round_trips = new_round_trips;
      p.image = &job->rgb;
      p.width = job->spec.settings.width;
      p.height = job->spec.settings.height;
      p.scene_name = job->spec.scene_name;
      p.rows_restored = job->board.rows_restored();
    }
    return p;
  }

  // A worker's line as the job's record has it.
  static WorkerView view_of(const WorkerRecord& r) {
    WorkerView v;
    v.serial = r.serial;
    v.name = r.name;
    v.weight = r.weight;
    v.task_rows = r.task_rows;
    v.tasks = r.tasks;
    v.rows = r.rows;
    v.busy_s = r.busy_s;
    v.state = r.state;
    return v;
  }

  // Registered workers, then the job's workers that are gone (lost or left).
  std::vector<WorkerView> worker_views() const {
    const auto now = Clock::now();
    std::vector<WorkerView> views;
    for (const auto& [id, w] : workers) {
      const bool in_job = job && job->record_of.count(w.serial);
      WorkerView v = in_job ? view_of(job->records[job->record_of.at(w.serial)]) : WorkerView{};
      v.serial = w.serial;
      v.name = w.info.name;
      v.weight = w.info.weight;
      v.task_rows = w.task_rows;
      v.in_flight = in_job ? job->policy.in_flight(w.serial) : 0;
      v.last_heard_s = since(w.last_heard, now);
      // A worker left out of the job (it failed it, or its results could not
      // be used) has no job loaded, but is not loading it.
      const bool left_out = in_job && (v.state == "failed" || v.state == "excluded");
      if (!left_out) v.state = job && w.loaded_job != job->spec.job ? "loading" : v.in_flight > 0 ? "rendering" : "idle";
      views.push_back(v);
    }
    if (!job) return views;
    for (const auto& [serial, when] : job->gone_at) {
      WorkerView v = view_of(job->records[job->record_of.at(serial)]);
      v.last_heard_s = since(when, now);
      views.push_back(v);
    }
    return views;
  }

  // Hands the turn's snapshot to `watch`, then forgets the news it carried.
  void report(const std::function<void(const FarmProgress&)>& watch) {
    if (watch) watch(snapshot());
    new_bands.clear();
    new_round_trips.clear();
  }

  void start_job(const FarmJob& in, const FarmHooks& hooks) {
    const JobSpec spec = early_matches(in) ? early->spec : spec_of(in);
    early.reset();
    early_asked = false;
    PolicyOptions policy = policy_options(cfg);
    if (last_row_costs.size() == static_cast<size_t>(spec.settings.height)) policy.prior_costs = last_row_costs;
    job = std::make_unique<ActiveJob>(spec, in, hooks, std::move(policy));
    job->t0 = Clock::now();
    new_bands = in.restored_rows;  // a watcher's copy of the image starts with them
    for (auto& [id, w] : workers) {
      add_record(w);
      // Loaded while the previous job finished: ready before this one began.
      auto pre = w.preloaded.find(spec.job);
      if (pre != w.preloaded.end()) {
        w.loaded_job = spec.job;
        WorkerRecord& rec = job->record(w.serial);
        rec.init_s = pre->second.second;
        rec.ready_at = since(job->t0, pre->second.first);  // negative: before this job's start
        if (job->first_ready < 0) job->first_ready = 0;
        job->policy.worker_ready(w.serial, 0);
      }
      w.preloaded.clear();
      auto failed = w.prefailed.find(spec.job);
      if (failed != w.prefailed.end()) on_job_failed(w, failed->second);
      w.prefailed.clear();
    }
    rejected.clear();
    send(pub, job->announcement);
    // PUB drops what a subscriber was not yet connected for; a heartbeat naming
    // the job tells any worker that missed the announcement to fetch it now.
    for (auto& [id, w] : workers) send_to(w, Heartbeat{spec.job});
    // The name is joined whole: printed into the buffer, a scene name of up
    // to 4096 bytes cut the line off, its hash, size and worker count with
    // it, or inside a character.
    char buf[160];
    std::snprintf(buf, sizeof buf, " (%s) %dx%d, %d spp, announced to %zu worker(s)", hash_hex(spec.scene_hash).c_str(),
                  spec.settings.width, spec.settings.height, spec.settings.spp, workers.size());
    log("job " + std::to_string(spec.job) + ": " + spec.scene_name + buf);
  }

  // Every row is in: tell the workers, and turn the job state into the record.
  FarmResult finish_job() {
    const double total = since(job->t0, Clock::now());
    last_row_costs = job->policy.row_costs();
    say_all_suppressed();
    send(pub, Message{JobDone{job->spec.job}});
    progress.finish(job->board.height(), total);
    JobRecordInput in;
    in.job = job->spec.job;
    in.scene_name = job->spec.scene_name;
    in.scene_hash = job->spec.scene_hash;
    in.settings = job->spec.settings;
    in.reference_weight = cfg.reference_weight;
    in.base_task_rows = cfg.base_task_rows;
    in.policy = policy_name(cfg.policy);
    in.backups = job->policy.backups();
    for (WorkerRecord& r : job->records) r.speed = job->policy.speed_of(r.serial);
    in.times.init_s = std::max(0.0, job->first_ready);
    in.times.render_s = job->last_result - std::max(0.0, job->first_dispatch);
    in.times.total_s = total;
    in.stats = job->stats;
    in.board = &job->board;
    in.workers = job->records;
    in.rejected = rejected;
    in.registrations_without_tasks = job->registrations_without_tasks;
    FarmResult out;
    out.width = job->spec.settings.width;
    out.height = job->spec.settings.height;
    out.record = make_job_record(in);
    out.rgb = std::move(job->rgb);
    out.stats = job->stats;
    return out;
  }
};

Broker::Broker(BrokerConfig config, LogSink log) : impl_(std::make_unique<Impl>(std::move(config), std::move(log))) {}
Broker::~Broker() = default;

std::string Broker::endpoint() const { return impl_->router_endpoint; }
std::string Broker::announce_endpoint() const { return impl_->pub_endpoint; }
size_t Broker::worker_count() const { return impl_->workers.size(); }
FarmProgress Broker::progress() const { return impl_->snapshot(); }

void Broker::drop_worker(const std::string& name, const std::string& why) {
  Impl& b = *impl_;
  // Every registration of the name: a worker that reconnected (a new socket)
  // is registered again while its old registration waits out its heartbeats,
  // and the first match by socket identity may be either one.
  for (auto it = b.workers.begin(); it != b.workers.end();) {
    auto next = std::next(it);
    if (it->second.info.name == name) b.drop_worker(it, "lost", why);
    it = next;
  }
}

FarmResult Broker::run(const FarmJob& job, const std::function<void(const FarmProgress&)>& watch,
                       const FarmHooks& hooks) {
  Impl& b = *impl_;
  validate_settings(job.settings);  // the rule every worker applies: refuse here, not on the fleet
  if (job.settings.width > b.cfg.max_image_width)
    throw InputError("image width " + std::to_string(job.settings.width) + " exceeds this broker's limit of " +
                     std::to_string(b.cfg.max_image_width) + " (its frame size cap)");
  check_image_memory(job.settings.width, job.settings.height, max_image_bytes(b.cfg),
                     "this broker's image limit (max_image_mib, or its memory)");
  if (job.scene_text.size() > protocol::kMaxSceneBytes)
    throw InputError(job.scene_name + ": larger than the protocol's 256 MiB scene limit");
  // A broker waiting in silence looks hung: the count is said once, and again as it changes.
  // A frame whose every row a restart restored (the crash came as it was being
  // saved) needs no worker: it is finished at once, whoever is connected.
  int told = -1;
  while (static_cast<int>(b.workers.size()) < b.cfg.min_workers && !restored_whole(job)) {
    if (const int registered = static_cast<int>(b.workers.size()); registered != told) {
      b.log("waiting for workers: " + std::to_string(registered) + " of the " + std::to_string(b.cfg.min_workers) +
            " needed (--min-workers)");
      told = registered;
    }
    b.turn(50);
    b.note_if_alone();
    b.report(watch);
  }
  if (!job.restored_rows.empty() &&
      job.restored_rgb.size() != static_cast<size_t>(job.settings.width) * job.settings.height * 3)
    throw std::invalid_argument("Broker::run: restored pixels do not fit the image");
  b.start_job(job, hooks);
  struct Reset {  // the job ends with this call, also when `watch` throws
    Impl& b;
    ~Reset() { b.job.reset(); }
  } reset{b};
  auto next_watch = Clock::now();
  while (!b.job->board.complete()) {
    b.turn(50);
    b.note_if_alone();
    if (b.job->failure) {
      // The lines held back may be the failing worker's own: their count comes
      // before the failure, which a one-shot broker reports as it exits.
      b.say_all_suppressed();
      send(b.pub, Message{JobDone{b.job->spec.job}});  // over, though not done: workers drop it
      throw FarmJobFailed("job " + std::to_string(b.job->spec.job) + " (" + b.job->spec.scene_name +
                          ") failed on the workers: " + *b.job->failure);
    }
    const auto now = Clock::now();
    if (now < next_watch) continue;  // a snapshot is O(workers): not after every message
    next_watch = now + kSweepPeriod;
    b.progress.update(b.job->board.rows_done(), b.job->board.height(), static_cast<int>(b.workers.size()),
                      since(b.job->t0, now), b.job->board.rows_restored());
    b.report(watch);
  }
  b.report(watch);  // the last results, which the rate limit above may have held back
  return b.finish_job();
}

void Broker::serve_for(double seconds) {
  const auto end = Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(seconds));
  while (Clock::now() < end) impl_->turn(20);
}

void Broker::shutdown_workers(double grace_s) {
  Impl& b = *impl_;
  b.shutting_down = true;
  send(b.pub, Message{Shutdown{}});
  for (auto& [id, w] : b.workers) send(b.router, Message{Shutdown{}}, &w.identity);
  b.workers.clear();
  b.by_serial.clear();
  serve_for(grace_s);
  b.shutting_down = false;
}

}  // namespace rayfarm
