// Status page routes; see status_routes.h.
#include "status/status_routes.h"

#include <httplib.h>

#include <thread>

#include "status/metrics.h"
#include "status/page_files.h"
#include "status/status_board.h"
#include "tracer/error.h"

namespace rayfarm {
namespace {

using nlohmann::json;

void answer(httplib::Response& res, int status, const json& body) {
  res.status = status;
  res.set_content(body.dump(), "application/json");
}

void not_found(httplib::Response& res, const std::string& what) { answer(res, 404, {{"error", what}}); }

// The page polls: answers must never come from a cache.
void no_store(httplib::Response& res) { res.set_header("Cache-Control", "no-store"); }

uint64_t job_of(const httplib::Request& req) { return std::stoull(req.matches[1].str()); }

}  // namespace

void mount_status_page(httplib::Server& server) {
  server.Get(R"(/|/index\.html|/status\.css|/status\.js)", [](const httplib::Request& req, httplib::Response& res) {
    const PageFile* f = find_page_file(req.path);
    if (!f) return not_found(res, "no such file");
    res.set_content(f->body.data(), f->body.size(), page_content_type(f->name));
  });
}

void mount_status_api(httplib::Server& server, const StatusBoard& board,
                      std::function<std::map<std::string, int>()> jobs_by_state) {
  server.Get("/api/workers", [&board](const httplib::Request&, httplib::Response& res) {
    no_store(res);
    answer(res, 200, board.workers_json());
  });
  server.Get(R"(/api/jobs/(\d{1,19})/preview\.png)", [&board](const httplib::Request& req, httplib::Response& res) {
    no_store(res);
    const auto png = board.preview_png(job_of(req));
    if (!png) return not_found(res, "no preview of job " + req.matches[1].str());
    res.set_content(*png, "image/png");
  });
  server.Get("/metrics", [&board, jobs_by_state](const httplib::Request&, httplib::Response& res) {
    FarmMetrics m = board.metrics();
    m.jobs_by_state = jobs_by_state();
    res.set_content(format_metrics(m), "text/plain; version=0.0.4; charset=utf-8");
  });
}

void mount_board_jobs(httplib::Server& server, const StatusBoard& board) {
  server.Get("/api/jobs", [&board](const httplib::Request&, httplib::Response& res) {
    no_store(res);
    answer(res, 200, board.jobs_json());
  });
  server.Get(R"(/api/jobs/(\d{1,19}))", [&board](const httplib::Request& req, httplib::Response& res) {
    no_store(res);
    const auto job = board.job_json(job_of(req));
    if (!job) return not_found(res, "no job " + req.matches[1].str());
    answer(res, 200, *job);
  });
  server.Get(R"(/api/jobs/(\d{1,19})/records/1)", [&board](const httplib::Request& req, httplib::Response& res) {
    no_store(res);
    const auto record = board.record(job_of(req));
    if (!record) return not_found(res, "no record of job " + req.matches[1].str() + " (yet)");
    answer(res, 200, *record);
  });
}

struct StatusServer::Impl {
  httplib::Server server;
  std::string host;
  int port = 0;
  std::thread thread;
};

StatusServer::StatusServer(const std::string& host, int port) : impl_(std::make_unique<Impl>()) {
  impl_->host = host;
  impl_->port = port == 0 ? impl_->server.bind_to_any_port(host) : (impl_->server.bind_to_port(host, port) ? port : -1);
  if (impl_->port <= 0)
    throw InputError("--http: cannot bind " + host + ":" + std::to_string(port) + " (in use, or no such address)");
}

StatusServer::~StatusServer() { stop(); }

httplib::Server& StatusServer::server() { return impl_->server; }

void StatusServer::start() {
  impl_->thread = std::thread([this] { impl_->server.listen_after_bind(); });
}

void StatusServer::stop() {
  impl_->server.stop();
  if (impl_->thread.joinable()) impl_->thread.join();
}

std::string StatusServer::address() const { return "http://" + impl_->host + ":" + std::to_string(impl_->port); }

}  // namespace rayfarm
