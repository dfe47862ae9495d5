// The farm worker's socket loop; see worker.h and protocol/SPEC.md.
#include "worker/worker.h"

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <optional>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <deque>
#include <set>
#include <thread>
#include <tuple>

#include <nlohmann/json.hpp>

#include "protocol/curve_keys.h"
#include "protocol/transport.h"
#include "tracer/log_text.h"
#include "tracer/renderer.h"
#include "worker/render_engine.h"
#include "worker/subscription_watch.h"

namespace rayfarm {
namespace {

using Clock = std::chrono::steady_clock;
using namespace protocol;
using TaskKey = std::tuple<uint64_t, uint32_t, uint32_t>;  // (job, task, attempt)

std::atomic<int> engine_counter{0};

}  // namespace

struct Worker::Impl {
  WorkerConfig cfg;
  std::function<void(const std::string&)> log_sink;
  std::unique_ptr<zmq::context_t> own_context;
  zmq::context_t& ctx;
  zmq::socket_t from_engine;
  std::unique_ptr<RenderEngine> engine;
  std::unique_ptr<zmq::socket_t> dealer, sub;
  std::unique_ptr<SubscriptionWatch> sub_watch;  // whether `sub` ever reached the broker
  int sub_port = 0;  // the broker's announce port `sub` dials (from a `welcome`; unused with --subscribe)
  bool subscribe_unresolved = false;  // --subscribe's host did not resolve at start: said then
  std::optional<CurveKeyPair> own_key;  // with broker_key: CURVE on both sockets
  std::string broker_key;
  std::unique_ptr<zmq::socket_t> handshakes;  // monitor of the DEALER's failed handshakes
  bool refusal_logged = false;

  bool registered = false;
  int broker_heartbeat_ms, broker_liveness;
  int backoff_ms;
  Clock::time_point last_recv, last_sent;
  bool reconnect_now = false;  // a socket could not be opened: start over after the back-off
  // Jobs whose scene the engine holds, latest last (it keeps two scenes, so
  // the next job can load while tasks of the current one are rendered).
  std::deque<uint64_t> loaded_jobs;
  uint64_t loading_job = 0, fetched_job = 0;
  // Jobs reported as job_failed, latest last: never fetched or loaded again.
  // Every one, not only the last: a broker still names a job this worker
  // failed (its current one, waiting for other workers, while the next is
  // announced early), and with only the last remembered the worker fetched
  // and failed two bad jobs in turn, loading each scene again. Bounded, as a
  // worker serves a head node for months: a broker names only its current
  // job and the one announced early, so a failed job it still asks about is
  // among the last few, and 64 leave room for many more (job ids differ
  // between broker runs, so an old one never comes back).
  std::deque<uint64_t> failed_jobs;
  static constexpr size_t kFailedJobsKept = 64;
  Clock::time_point fetched_at;
  std::optional<Clock::time_point> ready_sent_at;  // a `ready` the broker has not yet answered with `welcome`
  std::set<TaskKey> outstanding;  // tasks of this registration, so stale results are not sent
  int exit_code = -1;

  Impl(WorkerConfig c, std::function<void(const std::string&)> sink, zmq::context_t* shared)
      : cfg(std::move(c)), log_sink(std::move(sink)),
        own_context(shared ? nullptr : std::make_unique<zmq::context_t>(1)),
        ctx(shared ? *shared : *own_context),
        from_engine(ctx, zmq::socket_type::pair),
        broker_heartbeat_ms(cfg.heartbeat_ms), broker_liveness(cfg.liveness), backoff_ms(cfg.reconnect_initial_ms) {
    if (cfg.name.empty()) cfg.name = default_worker_name();
    // The broker drops a `ready` with a longer name: such a worker would never register, nor be told why.
    if (cfg.name.size() > kMaxNameBytes)
      throw InputError("worker: a name of " + std::to_string(cfg.name.size()) +
                       " bytes (--name, or \"name\" in its config or lab); the protocol allows at most " +
                       std::to_string(kMaxNameBytes));
    // JSON carries UTF-8 only: a name in another encoding (a Latin-1 "caf\xe9") cannot be sent at all.
    try {
      (void)nlohmann::json(cfg.name).dump();
    } catch (const nlohmann::json::type_error&) {
      throw InputError("worker: the name (--name, or \"name\" in its config or lab) is not valid UTF-8, the only "
                       "text the protocol carries");
    }
    // Logs print the name: a newline in it forged lines of this worker's own
    // log, and a NUL cut it short there while the job record kept it whole.
    if (const auto bad = std::find_if(cfg.name.begin(), cfg.name.end(),
                                      [](char c) { return static_cast<unsigned char>(c) < 0x20 || c == 0x7f; });
        bad != cfg.name.end()) {
      char byte[8];
      std::snprintf(byte, sizeof byte, "0x%02x", static_cast<unsigned char>(*bad));
      throw InputError("worker: the name (--name, or \"name\" in its config or lab) holds the control character " +
                       std::string(byte) + " at byte " + std::to_string(bad - cfg.name.begin() + 1));
    }
    if (cfg.connect.empty()) throw InputError("worker: no broker endpoint (--connect or \"connect\")");
    // Checked here: ZeroMQ would quietly dial another port, or one no broker
    // can be on, and retry it forever.
    if (const std::string problem = broker_endpoint_problem(cfg.connect); !problem.empty())
      throw InputError("cannot connect to the broker at '" + cfg.connect + "' (--connect or \"connect\"): " + problem);
    // Empty: the announcements' port comes from the broker's welcome.
    if (const std::string problem = cfg.subscribe.empty() ? "" : broker_endpoint_problem(cfg.subscribe);
        !problem.empty())
      throw InputError("cannot subscribe to the broker's announcements at '" + cfg.subscribe +
                       "' (--subscribe or \"subscribe\"): " + problem);
    if (cfg.key_file.empty() != cfg.broker_key_file.empty())
      throw InputError("worker: --key and --broker-key go together (this worker's secret key, the broker's public key)");
    if (!cfg.key_file.empty()) {
      own_key = load_secret_key(cfg.key_file);
      broker_key = load_public_key(cfg.broker_key_file);
    }
    from_engine.set(zmq::sockopt::linger, 0);
    const std::string inproc = "inproc://rayfarm-engine-" + std::to_string(engine_counter++);
    from_engine.bind(inproc);
    engine = std::make_unique<RenderEngine>(ctx, inproc, cfg.threads, cfg.throttle, cfg.max_isa);
  }

  // The broker's silence after which it counts as gone (a `ready` as lost, a
  // fetch as unanswered): its heartbeat and liveness once it has welcomed us,
  // until then our own.
  std::chrono::milliseconds broker_silence_limit() const {
    return std::chrono::milliseconds(silence_limit_ms(broker_heartbeat_ms, broker_liveness));
  }

  uint64_t loaded_job() const { return loaded_jobs.empty() ? 0 : loaded_jobs.back(); }
  bool has_loaded(uint64_t job) const {
    return std::find(loaded_jobs.begin(), loaded_jobs.end(), job) != loaded_jobs.end();
  }
  bool has_failed(uint64_t job) const {
    return std::find(failed_jobs.begin(), failed_jobs.end(), job) != failed_jobs.end();
  }
  void remember_failed(uint64_t job) {
    if (has_failed(job)) return;
    failed_jobs.push_back(job);
    if (failed_jobs.size() > kFailedJobsKept) failed_jobs.pop_front();
  }
  // Nothing to fetch or load: a job this worker holds, is loading or failed.
  bool needs_no_load(uint64_t job) const { return has_loaded(job) || job == loading_job || has_failed(job); }

  void log(const std::string& line, bool error = false) {
    if (cfg.quiet && !error) return;
    if (log_sink)
      log_sink(cfg.name + ": " + escape_control_characters(line));  // reasons the broker sent are in it
    else
      write_worker_log(cfg.name, line);
  }

  void to_broker(const Message& m) {
    send(*dealer, m);
    last_sent = Clock::now();
  }

  // ---- connection -------------------------------------------------------------

  void connect() {
    dealer = std::make_unique<zmq::socket_t>(ctx, zmq::socket_type::dealer);
    configure_socket(*dealer, kMaxBrokerFrameBytes);
    if (own_key) make_curve_client(*dealer, *own_key, broker_key);
    watch_handshakes();
    try {
      dealer->connect(cfg.connect);
    } catch (const zmq::error_t& e) {
      throw InputError("cannot connect to the broker at '" + cfg.connect + "' (--connect or \"connect\"): " + e.what() +
                       " (expected tcp://HOST:PORT)");
    }
    close_subscription();
    registered = false;
    broker_heartbeat_ms = cfg.heartbeat_ms;
    broker_liveness = cfg.liveness;
    last_recv = Clock::now();
    register_with_broker();
  }

  // A refused handshake (an uninvited key, or no key at a protected broker)
  // never reaches the protocol: without this monitor the worker would only
  // see a silent broker. Logged once per connection attempt cycle. A broker
  // that cannot open our CURVE hello (we hold another broker's public key),
  // or its announce port dialled by mistake, just drops the connection: that
  // is the "no detail" failure.
  void watch_handshakes() {
    close_handshake_monitor();
    const std::string endpoint = "inproc://rayfarm-handshake-" + std::to_string(engine_counter++);
    if (zmq_socket_monitor(dealer->handle(), endpoint.c_str(),
                           ZMQ_EVENT_HANDSHAKE_FAILED_AUTH | ZMQ_EVENT_HANDSHAKE_FAILED_PROTOCOL |
                               ZMQ_EVENT_HANDSHAKE_FAILED_NO_DETAIL) != 0)
      throw zmq::error_t();
    handshakes = std::make_unique<zmq::socket_t>(ctx, zmq::socket_type::pair);
    handshakes->set(zmq::sockopt::linger, 0);
    handshakes->connect(endpoint);
    refusal_logged = false;
  }

  void close_handshake_monitor() {
    if (handshakes && dealer) zmq_socket_monitor(dealer->handle(), nullptr, 0);
    handshakes.reset();
  }

  void on_handshake_event(const Frames& frames) {
    if (frames.size() != 2 || frames[0].size() != 6 || refusal_logged) return;
    uint16_t event = 0;
    uint32_t status = 0;
    std::memcpy(&event, frames[0].data(), 2);
    std::memcpy(&status, frames[0].data() + 2, 4);
    refusal_logged = true;
    if (event == ZMQ_EVENT_HANDSHAKE_FAILED_AUTH)
      log("the broker refused this worker (authentication failed, status " + std::to_string(status) + "): " +
              (own_key ? "its key " + own_key->public_key + " is not invited; the broker's admin must add its .pub "
                                                            "to the --allow folder"
                       : "the broker admits only invited keys or loopback peers; give --key and --broker-key"),
          true);
    else if (event == ZMQ_EVENT_HANDSHAKE_FAILED_NO_DETAIL)
      log("the broker at " + cfg.connect + " closed the connection during the handshake: is that its worker port " +
              "(not its announce port), " +
              (own_key ? "and does --broker-key " + cfg.broker_key_file + " (" + broker_key +
                             ") hold its public key? (a broker logs its key, or that it has none, and its ports at start)"
                       : "and does it run without keys? " + keyless_advice()),
          true);
    else
      log("the broker at " + cfg.connect + " refused the handshake (protocol error): " + mechanism_mismatch_advice(),
          true);
  }

  // A protocol error in the handshake is the two sides speaking different
  // mechanisms: keys on one side only. Which side lacks them follows from
  // this worker's own configuration. (Which of the two events a keyed broker
  // raises at a keyless worker is a race: both give the same advice.)
  std::string mechanism_mismatch_advice() const {
    if (own_key)
      return "this worker uses CURVE (--key " + cfg.key_file + ", --broker-key " + cfg.broker_key_file +
             "); does the broker run with --key? (a broker logs its key, or that it has none, at start)";
    return keyless_advice();
  }

  static std::string keyless_advice() {
    return "This worker has no keys, and the broker may require them: give it --key (its secret key, invited to the "
           "broker's --allow folder) and --broker-key (the broker's .pub)";
  }

  // The count the render engine will use (never 0 for "all cores", never more
  // than this machine has): the broker's log, the job record and a farm's
  // --stats say how many threads rendered.
  int threads_rendering() const { return render_threads(cfg.threads); }

  void register_with_broker() {
    engine->clear();
    outstanding.clear();
    to_broker(Ready{cfg.name, cfg.weight, threads_rendering(), cfg.credit, cfg.heartbeat_ms, cfg.throttle});
    ready_sent_at = Clock::now();
  }

  // A `ready` unanswered for less than a liveness period is still on its way
  // (after that it counts as lost and is sent again): the broker requeues
  // every task it handed out before it.
  bool awaiting_welcome() const {
    return ready_sent_at &&
           Clock::now() - *ready_sent_at < broker_silence_limit();
  }

  // Paranoid Pirate: the broker missed `liveness` heartbeats. Drop everything
  // it gave us (it requeues them), wait, reconnect, register again.
  void reconnect(const std::atomic<bool>& stop) {
    const std::string silence = std::to_string(broker_silence_limit().count()) + " ms";
    // Not yet registered on this connection: no broker has answered there, which
    // is a broker not (yet) up, an address that is not its worker port, or a
    // host name that does not resolve (yet: DNS may come up after the worker).
    const std::string unresolved = registered ? "" : tcp_host_problem(cfg.connect);
    log((registered           ? "broker silent for " + silence
         : unresolved.empty() ? "no broker answered at " + cfg.connect + " within " + silence
                              : "cannot reach the broker at " + cfg.connect + ": " + unresolved) +
        "; reconnecting in " + std::to_string(backoff_ms) + " ms");
    engine->clear();
    outstanding.clear();
    for (;;) {
      close_handshake_monitor();
      dealer.reset();
      close_subscription();
      const auto until = Clock::now() + std::chrono::milliseconds(backoff_ms);
      while (Clock::now() < until && !stop) std::this_thread::sleep_for(std::chrono::milliseconds(20));
      backoff_ms = std::min(backoff_ms * 2, cfg.reconnect_max_ms);
      if (stop) return;
      try {
        connect();
        return;
      } catch (const zmq::error_t& e) {
        if (!out_of_sockets(e)) throw;
        log(std::string("cannot open a socket yet (") + e.what() + "); retrying in " + std::to_string(backoff_ms) +
            " ms");
      }
    }
  }

  // libzmq frees a closed socket's slot (and file descriptors) later, in its
  // reaper thread: when hundreds of lab workers sharing one context reconnect
  // at once on a loaded machine, their old sockets may still hold every slot,
  // and opening a new one fails with EMFILE. That passes: wait and retry.
  static bool out_of_sockets(const zmq::error_t& e) { return e.num() == EMFILE; }

  void open_subscription(int pub_port) {
    const std::string endpoint = cfg.subscribe.empty() ? endpoint_with_port(cfg.connect, pub_port) : cfg.subscribe;
    sub = std::make_unique<zmq::socket_t>(ctx, zmq::socket_type::sub);
    configure_socket(*sub, kMaxBrokerFrameBytes);
    if (own_key) make_curve_client(*sub, *own_key, broker_key);
    sub->set(zmq::sockopt::subscribe, "");
    sub_watch = std::make_unique<SubscriptionWatch>(
        ctx, *sub, endpoint, cfg.subscribe.empty() ? "the announce port of the broker's welcome" : "--subscribe");
    sub->connect(endpoint);
    sub_port = pub_port;
  }

  void close_subscription() {
    sub_watch.reset();  // stops watching while `sub` is still open
    sub.reset();
  }

  // Said once per subscription, as an error (also with --quiet): no
  // announcement will come, and nothing else would say so.
  void watch_subscription() {
    if (!sub_watch) return;
    if (const std::string reached = sub_watch->serve_pending(); !reached.empty()) log(reached);
    if (subscribe_unresolved) return;  // its reason was said at start
    if (const std::string unreached = sub_watch->overdue(broker_silence_limit()); !unreached.empty())
      log(unreached, true);
  }

  // A broker restarted on the same worker port re-registers us on the same
  // connection (`reregister`), so the subscription stays up; if it now
  // announces on another port, the old one would hear nothing again (or
  // another broker's jobs): its jobs came only by fetch, a heartbeat later,
  // and its `shutdown` announcement never.
  bool announce_port_moved(int pub_port) const { return sub && cfg.subscribe.empty() && pub_port != sub_port; }

  // ---- jobs -------------------------------------------------------------------

  // The broker named its current job; fetch it over ROUTER if we missed the
  // announcement (Clone pattern). Re-fetch only after a liveness period.
  void job_hint(uint64_t job) {
    if (job == 0 || needs_no_load(job)) return;
    const auto now = Clock::now();
    if (job == fetched_job && now - fetched_at < broker_silence_limit())
      return;
    fetched_job = job;
    fetched_at = now;
    to_broker(FetchJob{job});
  }

  void start_load(const JobSpec& spec) {
    if (needs_no_load(spec.job)) return;
    loading_job = spec.job;
    engine->load(spec);
  }

  // ---- incoming -----------------------------------------------------------------

  void from_broker(const Frames& frames) {
    if (exit_code >= 0) return;  // stopping: what else queued is not read
    Message m;
    try {
      m = decode(frames);
    } catch (const ProtocolError& e) {
      if (const auto other = other_version(frames)) return stop_for_version(*other);
      log(std::string("rejected message from broker: ") + e.what(), true);
      return;
    }
    last_recv = Clock::now();
    if (auto* w = std::get_if<Welcome>(&m)) {
      // Registered: adopt the broker's heartbeat, subscribe to its
      // announcements, and report a job we already have loaded (reconnect).
      registered = true;
      ready_sent_at.reset();
      backoff_ms = cfg.reconnect_initial_ms;
      broker_heartbeat_ms = w->heartbeat_ms;
      broker_liveness = w->liveness;
      if (w->liveness < kMinSilentIntervals)
        log("the broker's liveness " + std::to_string(w->liveness) + " would count it gone at its first quiet " +
            "heartbeat interval; waiting " + std::to_string(kMinSilentIntervals) + " intervals (" +
            std::to_string(broker_silence_limit().count()) + " ms) instead");
      if (announce_port_moved(w->pub_port)) {
        log("the broker announces on port " + std::to_string(w->pub_port) + " now, not " + std::to_string(sub_port) +
            "; subscribing there");
        close_subscription();
      }
      if (!sub) {
        try {
          open_subscription(w->pub_port);
        } catch (const zmq::error_t& e) {
          if (!out_of_sockets(e)) throw;
          log(std::string("cannot subscribe yet (") + e.what() + "); reconnecting");
          reconnect_now = true;
          return;
        }
      }
      log("registered with " + cfg.connect);
      if (w->job != 0 && has_loaded(w->job)) to_broker(JobReady{w->job, 0});
      job_hint(w->job);
    } else if (auto* h = std::get_if<Heartbeat>(&m)) {
      job_hint(h->job);
    } else if (auto* j = std::get_if<JobSpec>(&m)) {
      start_load(*j);
    } else if (auto* t = std::get_if<TaskAssign>(&m)) {
      // A task that comes while our `ready` is on its way was sent before the
      // broker read that `ready`, which requeues it (no task follows a `ready`
      // before its `welcome`): rendered, it cost a task's time for a stale
      // result; of a job we do not hold, it sent another `ready` per task,
      // registering us again and again.
      if (awaiting_welcome()) return;
      if (!has_loaded(t->job)) {
        // The broker believes we have a job we do not: registering again makes
        // it requeue the task and start over from `welcome`.
        log("got a task of job " + std::to_string(t->job) + ", which is not loaded; registering again", true);
        return register_with_broker();
      }
      outstanding.insert({t->job, t->task, t->attempt});
      engine->render(*t);
    } else if (auto* r = std::get_if<Reregister>(&m)) {
      // A restarted broker answers each heartbeat that queued while it was
      // down with its own `reregister`, all of them sent before our `ready`
      // reached it: one `ready` answers them all. Another would register us
      // again, and the tasks handed out in between would be requeued. Only a
      // `ready` unanswered for a liveness period is sent again.
      if (awaiting_welcome()) return;
      log("broker asks to re-register (" + r->reason + ")");
      register_with_broker();
    } else if (std::holds_alternative<Shutdown>(m)) {
      log("shutdown by broker");
      exit_code = 0;
    } else {
      log(std::string("rejected '") + type_name(m) + "' from broker: not a broker-to-worker message");
    }
  }

  // The broker speaks another protocol version (it refuses our `ready` so,
  // in its own version): no retry can change that, and retrying for ever
  // looked like a broker that is merely slow. The worker stops, non-zero.
  void stop_for_version(const OtherVersion& other) {
    log("the broker at " + cfg.connect + " speaks protocol version " + std::to_string(other.version) +
            " and this worker version " + std::to_string(kVersion) +
            (other.reason.empty() ? std::string() : " (the broker said: " + other.reason + ")") +
            "; they cannot work together, so this worker stops: run the broker's rayfarm release on this machine",
        true);
    exit_code = 1;
  }

  void from_announcements(const Frames& frames) {
    Message m;
    try {
      m = decode(frames);
    } catch (const ProtocolError& e) {
      log(std::string("rejected announcement: ") + e.what());
      return;
    }
    if (auto* j = std::get_if<JobSpec>(&m)) {
      start_load(*j);
    } else if (std::holds_alternative<Shutdown>(m)) {
      log("shutdown announced");
      exit_code = 0;
    }
  }

  // Events from our own render thread (typed, nothing to decode): job loaded,
  // task rendered, job failed, task skipped (or stopped: an AbandonedTask
  // needs nothing). Results are forwarded only for tasks of the current
  // registration; the broker has requeued anything older.
  void from_render_thread(EngineEvent& event) {
    if (auto* r = std::get_if<JobReady>(&event)) {
      loaded_jobs.push_back(r->job);
      while (loaded_jobs.size() > RenderEngine::kLoaded) loaded_jobs.pop_front();  // as many as the engine keeps
      if (loading_job == r->job) loading_job = 0;
      char buf[96];
      std::snprintf(buf, sizeof buf, "job %llu ready (init %.3f s)", static_cast<unsigned long long>(r->job), r->init_s);
      log(buf);
      to_broker(*r);
    } else if (auto* res = std::get_if<TaskResult>(&event)) {
      if (outstanding.erase({res->job, res->task, res->attempt})) to_broker(*res);
    } else if (auto* f = std::get_if<JobFailed>(&event)) {
      // Report and drop the job, but stay up: the next job may be fine.
      log("cannot render job " + std::to_string(f->job) + " (" + scope_name(f->scope) + "): " + f->reason, true);
      remember_failed(f->job);
      if (loading_job == f->job) loading_job = 0;
      loaded_jobs.erase(std::remove(loaded_jobs.begin(), loaded_jobs.end(), f->job), loaded_jobs.end());
      engine->clear(f->job);  // a second loaded job's tasks render on
      for (auto it = outstanding.begin(); it != outstanding.end();)
        it = std::get<0>(*it) == f->job ? outstanding.erase(it) : std::next(it);
      to_broker(*f);
    } else if (auto* skipped = std::get_if<SkippedTask>(&event)) {
      if (awaiting_welcome()) return;  // the `ready` on its way has the broker requeue it
      log("task " + std::to_string(skipped->task) + " belongs to a job no longer loaded; registering again", true);
      register_with_broker();  // the broker requeues everything we held
    }
  }

  // ---- loop ---------------------------------------------------------------------

  template <class Fn> static void drain(zmq::socket_t* s, Fn&& fn) {
    if (!s) return;
    for (int i = 0; i < 1000; ++i) {
      auto frames = receive(*s);
      if (!frames) return;
      fn(*frames);
    }
  }

  // The socket loop never renders: it polls at least every 100 ms (half a
  // heartbeat if shorter) so heartbeats go out on time while cores are busy.
  int run(const std::atomic<bool>& stop) {
    // The render engine takes no more threads than the machine runs at once,
    // and the broker is told (and records) that count: said here, once, as
    // `render --threads` says it, or a config asking for more went unremarked.
    if (cfg.threads > threads_rendering())
      log("threads " + std::to_string(cfg.threads) + " (--threads, or \"threads\" in its config or lab): this " +
          "machine runs " + std::to_string(threads_rendering()) + " threads at once; rendering on " +
          std::to_string(threads_rendering()));
    // Said at once, not after a liveness period of silence; the worker still
    // retries, as one started before its DNS is up must.
    if (const std::string unresolved = tcp_host_problem(cfg.connect); !unresolved.empty())
      log("cannot reach the broker at " + cfg.connect + ": " + unresolved + "; retrying until it resolves", true);
    // ZeroMQ retries an unresolvable --subscribe host in silence, and the
    // worker still renders (it fetches each job on its worker socket): without
    // this line nothing ever said that the announcements do not arrive.
    if (const std::string unresolved = tcp_host_problem(cfg.subscribe); !unresolved.empty()) {
      subscribe_unresolved = true;
      log("cannot subscribe to the broker's announcements at " + cfg.subscribe + ": " + unresolved +
              "; retrying until it resolves (meanwhile each job is fetched when the broker names it, later than "
              "an announcement would bring it)",
          true);
    }
    connect();
    while (exit_code < 0) {
      if (stop) {
        if (dealer) to_broker(Bye{});
        exit_code = 0;
        break;
      }
      std::vector<zmq::pollitem_t> items = {{dealer->handle(), 0, ZMQ_POLLIN, 0},
                                            {from_engine.handle(), 0, ZMQ_POLLIN, 0}};
      if (sub) items.push_back({sub->handle(), 0, ZMQ_POLLIN, 0});
      if (handshakes) items.push_back({handshakes->handle(), 0, ZMQ_POLLIN, 0});
      if (sub_watch) items.push_back({sub_watch->socket().handle(), 0, ZMQ_POLLIN, 0});
      const int wait_ms = std::max(1, std::min(100, cfg.heartbeat_ms / 2));
      poll_interruptible(items.data(), items.size(), wait_ms);
      drain(dealer.get(), [&](const Frames& f) { from_broker(f); });
      drain(&from_engine, [](const Frames&) {});  // doorbell rings: the events are queued in the engine
      for (EngineEvent& e : engine->take_events()) from_render_thread(e);
      drain(sub.get(), [&](const Frames& f) { from_announcements(f); });
      drain(handshakes.get(), [&](const Frames& f) { on_handshake_event(f); });
      watch_subscription();
      if (exit_code >= 0) break;
      const auto now = Clock::now();
      if (now - last_sent >= std::chrono::milliseconds(cfg.heartbeat_ms)) to_broker(Heartbeat{loaded_job()});
      if (reconnect_now || now - last_recv > broker_silence_limit()) {
        reconnect_now = false;
        reconnect(stop);
      }
    }
    engine.reset();  // joins the render thread (after its current task)
    if (dealer) dealer->set(zmq::sockopt::linger, 500);  // let a last `bye` leave
    close_handshake_monitor();
    dealer.reset();
    close_subscription();
    return exit_code;
  }
};

Worker::Worker(WorkerConfig config, std::function<void(const std::string&)> log, zmq::context_t* context)
    : impl_(std::make_unique<Impl>(std::move(config), std::move(log), context)) {}
Worker::~Worker() = default;

int Worker::run(const std::atomic<bool>& stop) { return impl_->run(stop); }

void write_worker_log(const std::string& name, const std::string& line) {
  std::fprintf(stderr, "rayfarm worker %s\n", escape_control_characters(name + ": " + line).c_str());
}

}  // namespace rayfarm
