// The status page's files (status/web/: HTML, CSS, JavaScript), compiled into
// the binary by a build step (cmake/embed_files.cmake), so a head node serves
// the page with nothing installed beside the executable and the page loads
// nothing from the internet. index.html is the page; the rest it links to.
#pragma once

#include <string_view>
#include <vector>

namespace rayfarm {

struct PageFile {
  std::string_view name;  // e.g. "index.html", "status.js"
  std::string_view body;
};

// Every file, index.html first (generated source).
const std::vector<PageFile>& page_files();

// The file served at URL path `path` ("/" is index.html, "/status.js" is
// status.js); nullptr for anything else.
const PageFile* find_page_file(std::string_view path);

// The Content-Type for a file name, from its extension.
const char* page_content_type(std::string_view name);

// Total bytes of the page's files.
size_t page_bytes();

}  // namespace rayfarm
