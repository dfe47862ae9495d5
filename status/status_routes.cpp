// Status page routes; see status_routes.h.
#include "status/status_routes.h"

#include <httplib.h>

#include "status/metrics.h"
#include "status/page_files.h"
#include "status/route_table.h"
#include "status/status_board.h"

namespace rayfarm {
namespace {

void not_found(httplib::Response& res, const std::string& what) {
  res.status = 404;
  res.set_content(nlohmann::json{{"error", what}}.dump(), "application/json");
}

// The page polls: answers must never come from a cache.
void no_store(httplib::Response& res) { res.set_header("Cache-Control", "no-store"); }

}  // namespace

void mount_status_page(RouteTable& routes) {
  routes.get(R"(/|/index\.html|/status\.css|/status\.js)", [](const httplib::Request& req, httplib::Response& res) {
    const PageFile* f = find_page_file(req.path);
    if (!f) return not_found(res, "no such file");
    res.set_content(f->body.data(), f->body.size(), page_content_type(f->name));
  });
}

void mount_status_api(RouteTable& routes, const StatusBoard& board, StatusSources sources) {
  routes.get("/api/workers", [&board](const httplib::Request&, httplib::Response& res) {
    no_store(res);
    res.set_content(board.workers_json().dump(), "application/json");
  });
  routes.get("/api/service", [&board](const httplib::Request&, httplib::Response& res) {
    no_store(res);
    res.set_content(board.service_json().dump(), "application/json");
  });
  const std::string preview = std::string("/api/jobs/") + kPathNumber + R"(/preview\.png)";
  routes.get(preview, [&board, sources](const httplib::Request& req, httplib::Response& res) {
    no_store(res);
    const uint64_t job = std::stoull(req.matches[1].str());
    auto png = board.preview_png(job);
    if (!png && sources.finished_png) png = sources.finished_png(job);
    if (!png) return not_found(res, "no image of job " + req.matches[1].str() + " (yet)");
    res.set_content(*png, "image/png");
  });
  routes.get("/metrics", [&board, sources](const httplib::Request&, httplib::Response& res) {
    FarmMetrics m = board.metrics();
    if (sources.jobs_by_state) m.jobs_by_state = sources.jobs_by_state();
    res.set_content(format_metrics(m), "text/plain; version=0.0.4; charset=utf-8");
  });
}

}  // namespace rayfarm
