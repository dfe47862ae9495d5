// Lookup over the embedded page files; see page_files.h (the table itself is
// generated into the build folder).
#include "status/page_files.h"

namespace rayfarm {
namespace {

bool ends_with(std::string_view s, std::string_view suffix) {
  return s.size() >= suffix.size() && s.substr(s.size() - suffix.size()) == suffix;
}

}  // namespace

const PageFile* find_page_file(std::string_view path) {
  if (path == "/") path = "/index.html";
  if (path.empty() || path.front() != '/') return nullptr;
  path.remove_prefix(1);
  for (const PageFile& f : page_files())
    if (f.name == path) return &f;
  return nullptr;
}

const char* page_content_type(std::string_view name) {
  if (ends_with(name, ".html")) return "text/html; charset=utf-8";
  if (ends_with(name, ".css")) return "text/css; charset=utf-8";
  if (ends_with(name, ".js")) return "text/javascript; charset=utf-8";
  if (ends_with(name, ".svg")) return "image/svg+xml";
  return "application/octet-stream";
}

size_t page_bytes() {
  size_t total = 0;
  for (const PageFile& f : page_files()) total += f.body.size();
  return total;
}

}  // namespace rayfarm
