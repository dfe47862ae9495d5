// The long-running broker service; see farm_service.h.
#include "service/farm_service.h"

#include <unistd.h>

#include <chrono>
#include <cstring>
#include <filesystem>
#include <new>
#include <optional>

#include "tracer/elapsed.h"
#include "tracer/error.h"
#include "tracer/image_memory.h"

namespace rayfarm {
namespace {

using Clock = std::chrono::steady_clock;

// Thrown from the broker's watch to leave Broker::run.
struct FrameAbandoned {
  const char* why;
};

// The pixels and rows a restart restored, in the shape Broker::run resumes from.
FarmJob farm_job_of(const FrameWork& f) {
  FarmJob job{f.scene.text, f.scene.name, f.settings, {}, {}, {}};
  if (f.restored.empty()) return job;
  const size_t row_floats = static_cast<size_t>(f.settings.width) * 3;
  job.restored_rgb.assign(row_floats * f.settings.height, 0.0f);
  for (const RowBand& b : f.restored) {
    std::memcpy(&job.restored_rgb[row_floats * b.y0], b.rgb.data(), b.rgb.size() * sizeof(float));
    job.restored_rows.emplace_back(b.y0, b.y1);
    job.restored_stats += b.stats;
  }
  return job;
}

// `path` from the root ("k/allow" -> "/srv/head/k/allow"); as given if the
// working folder is gone.
std::string absolute_path(const std::string& path) {
  std::error_code error;
  const std::filesystem::path full = std::filesystem::absolute(path, error);
  return error ? path : full.lexically_normal().string();
}

}  // namespace

struct FarmService::Impl {
  ServeOptions options;
  JobService jobs;
  StatusBoard status;  // the status page's live view, fed by this thread
  HttpApi http;        // before the broker: a refused API address binds no worker port
  Broker broker;
  // When the previous frame's last row was accepted: the gap to this frame's
  // first hand-out is what announcing early saves.
  std::optional<Clock::time_point> last_row_at;

  // The jobs write their lines with write_log, escaped: they get the sink
  // itself, as the broker does, not log(), which escaped them again (a
  // backslash in DIR came out as four).
  explicit Impl(const ServeOptions& o)
      : options(o), jobs(o.state_dir, max_image_bytes(o.broker), o.log, o.stop),
        http(jobs, o.http, &status, [this](const std::string& line) { log(line); }),
        broker(o.broker, o.log) {
    const nlohmann::json where = {{"http", http.address()},
                                  {"workers", broker.endpoint()},
                                  {"announce", broker.announce_endpoint()},
                                  {"pid", static_cast<long>(::getpid())}};
    jobs.store().write_note("service.json", where.dump(2) + "\n");
    status.set_worker_endpoint(broker.endpoint());  // the page's "start a worker" hint names its port
    // On a keyed farm a worker without --key and --broker-key is never
    // admitted: the hint names them (the public key file, not the secret one),
    // as absolute paths: the page is read far from the broker's working folder.
    if (!o.broker.key_file.empty())
      status.set_worker_keys(broker_public_key_beside(absolute_path(o.broker.key_file)),
                             absolute_path(o.broker.allow_dir));
    log("serving " + http.address() + "; workers connect to " + broker.endpoint() + "; state in " + o.state_dir);
  }

  void log(const std::string& line) { write_log(options.log, line); }

  void render(const FrameWork& f, const std::atomic<bool>& stop) {
    double journal_s = 0;
    std::optional<double> gap_s;
    bool first_sent = true;
    FarmHooks hooks;
    hooks.sent = [&](const PixelBand& task) {
      const auto t0 = Clock::now();
      if (first_sent && last_row_at) gap_s = std::chrono::duration<double>(t0 - *last_row_at).count();
      first_sent = false;
      // A row cut into spans is journaled as sent once, with its first span
      // (the journal counts rows in flight at a crash, to be rendered again).
      if (task.x0 == 0) jobs.rows_sent(f, task.y0, task.y1);
      journal_s += seconds_since(t0);
    };
    hooks.accepted = [&](const protocol::TaskResult& r) {
      const auto t0 = Clock::now();
      jobs.rows_accepted(f, RowBand{f.frame, r.y0, r.y1, r.width, r.stats, r.rgb});
      last_row_at = Clock::now();
      journal_s += std::chrono::duration<double>(*last_row_at - t0).count();
    };
    hooks.upcoming = [&]() -> std::optional<FarmJob> {
      const auto next = jobs.frame_after(f);
      return next ? std::optional<FarmJob>(farm_job_of(*next)) : std::nullopt;
    };
    auto watch = [&](const FarmProgress& progress) {
      status.update(progress, f.job);
      if (stop) throw FrameAbandoned{"the service is stopping"};
      if (!jobs.is_running(f.job)) throw FrameAbandoned{"the job was cancelled"};
    };
    log("job " + std::to_string(f.job) + " frame " + std::to_string(f.frame + 1) + "/" + std::to_string(f.frames) +
        ": " + f.scene.name + (f.restored.empty() ? "" : ", resuming with journaled rows"));
    try {
      const FarmResult r = broker.run(farm_job_of(f), watch, hooks);
      nlohmann::json record = r.record;
      record["journal_s"] = journal_s;
      // Previous frame's last row -> this frame's first hand-out; null for the
      // first frame this process rendered.
      record["gap_s"] = gap_s ? nlohmann::json(*gap_s) : nlohmann::json(nullptr);
      jobs.frame_finished(f, r.rgb, record);
      char buf[160];
      std::snprintf(buf, sizeof buf, "job %llu frame %u done in %.2f s (journal %.4f s, resumed %d rows)",
                    static_cast<unsigned long long>(f.job), f.frame + 1, r.record["total_s"].get<double>(), journal_s,
                    r.record["resumed_rows"].get<int>());
      log(buf);
    } catch (const StateFault& e) {
      // The frame cannot be saved (a full disk, a read-only folder): failing
      // the job would drop its journaled rows, and every queued job would fail
      // after it the same way. The service stops; restarted once the folder
      // takes writes, it finishes the frame from the journal.
      log("job " + std::to_string(f.job) + " frame " + std::to_string(f.frame + 1) +
          " cannot be saved; the service stops, its rows stay journaled for the next start: " + e.what());
      throw;
    } catch (const FrameAbandoned& a) {
      last_row_at.reset();
      log("job " + std::to_string(f.job) + " frame " + std::to_string(f.frame + 1) + " stopped: " + a.why);
    } catch (const InputError& e) {
      // The job itself is bad (e.g. settings this broker refuses); the service goes on.
      fail(f, e.what());
    } catch (const FarmJobFailed& e) {
      // The workers could not render it (its scene, or two sick machines): the
      // job fails with their reason, its journaled rows kept; the queue goes on.
      fail(f, e.what());
    } catch (const std::bad_alloc&) {
      // Within the image limit but more than the head node has free (the
      // broker holds the frame whole, the status page a copy): were the
      // service to die, it would meet the same job again after its restart.
      char why[160];
      std::snprintf(why, sizeof why, "the broker ran out of memory for this %dx%d frame (%.1f GiB as float RGB)",
                    f.settings.width, f.settings.height,
                    double(float_image_bytes(f.settings.width, f.settings.height)) / double(1ull << 30));
      fail(f, why);
    }
  }

  void fail(const FrameWork& f, const std::string& why) {
    last_row_at.reset();
    jobs.fail(f.job, why);
    log("job " + std::to_string(f.job) + " failed: " + why);
  }
};

FarmService::FarmService(const ServeOptions& options) : impl_(std::make_unique<Impl>(options)) {}
FarmService::~FarmService() = default;

void FarmService::run(const std::atomic<bool>& stop) {
  while (!stop) {
    const auto frame = impl_->jobs.next_frame();
    if (frame)
      impl_->render(*frame, stop);
    else {
      impl_->broker.serve_for(0.05);  // heartbeats and registrations while idle
      impl_->status.update(impl_->broker.progress());
    }
  }
}

void FarmService::log_stop(const std::string& cause) {
  impl_->log("stopping on " + cause + ": " + impl_->jobs.left_to_resume());
}

std::string FarmService::http_address() const { return impl_->http.address(); }
const Broker& FarmService::broker() const { return impl_->broker; }

}  // namespace rayfarm
