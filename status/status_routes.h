// The status page's HTTP routes, mounted on the service's cpp-httplib server
// through its route table (status/route_table.h, service/http_api.h): the
// page itself at "/" (status/page_files.h) and the live parts of the API
// from a StatusBoard -- the worker table, the worker endpoint, job previews
// and /metrics. The jobs themselves come from the job service's own routes.
// What each route answers: docs/status-page.md.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <string>

namespace rayfarm {

class RouteTable;
class StatusBoard;

struct StatusSources {
  // The jobs gauge of /metrics: the job queue's count per state.
  std::function<std::map<std::string, int>()> jobs_by_state;
  // The image of a job the board no longer keeps (e.g. finished before a
  // restart), as a PNG; nullopt if there is none (404).
  std::function<std::optional<std::string>(uint64_t job)> finished_png;
};

// "/", "/index.html", "/status.css", "/status.js" (public: no token needed).
void mount_status_page(RouteTable& routes);

// GET /api/workers, /api/service, /api/jobs/ID/preview.png and /metrics.
void mount_status_api(RouteTable& routes, const StatusBoard& board, StatusSources sources);

}  // namespace rayfarm
