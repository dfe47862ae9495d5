// The status page's HTTP routes, mounted on a cpp-httplib server: the page
// itself at "/" (status/page_files.h), the live parts of the API from a
// StatusBoard (workers, job previews, /metrics), and -- for a host without a
// job service -- the jobs the board has seen.
#pragma once

#include <functional>
#include <map>
#include <memory>
#include <string>

namespace httplib {
class Server;
}

namespace rayfarm {

class StatusBoard;

// "/", "/index.html", "/status.css", "/status.js".
void mount_status_page(httplib::Server& server);

// GET /api/workers, /api/jobs/ID/preview.png and /metrics. `jobs_by_state`
// gives the jobs gauge of /metrics (the job queue's counts).
void mount_status_api(httplib::Server& server, const StatusBoard& board,
                      std::function<std::map<std::string, int>()> jobs_by_state);

// GET /api/jobs, /api/jobs/ID and /api/jobs/ID/records/1 from the board.
void mount_board_jobs(httplib::Server& server, const StatusBoard& board);

// A cpp-httplib server on its own thread, bound at construction.
class StatusServer {
 public:
  // Binds HOST:PORT (port 0 = any free port); throws InputError if it cannot.
  StatusServer(const std::string& host, int port);
  ~StatusServer();  // stops serving and joins the thread
  StatusServer(const StatusServer&) = delete;
  StatusServer& operator=(const StatusServer&) = delete;

  httplib::Server& server();  // mount routes before start()
  void start();
  void stop();
  std::string address() const;  // "http://127.0.0.1:41234"

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace rayfarm
