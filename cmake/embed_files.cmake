# Writes a C++ source holding files as byte arrays, for a page compiled into
# the binary (status/page_files.h). Run as a script at build time:
#   cmake -DOUTPUT=out.cpp -DBASE=dir -DFILES=a.html,b.js -P embed_files.cmake
# Each file becomes {"name", bytes}; the table's order is FILES' order.
cmake_minimum_required(VERSION 3.20)
string(REPLACE "," ";" FILES "${FILES}")
set(arrays "")
set(table "")
set(index 0)
foreach(name IN LISTS FILES)
  file(READ "${BASE}/${name}" hex HEX)
  string(LENGTH "${hex}" hex_length)
  math(EXPR size "${hex_length} / 2")
  string(REGEX REPLACE "([0-9a-f][0-9a-f])" "0x\\1," bytes "${hex}")
  string(APPEND arrays "const unsigned char file${index}[] = {${bytes}0x00};\n")
  string(APPEND table "      {\"${name}\", std::string_view(reinterpret_cast<const char*>(file${index}), ${size})},\n")
  math(EXPR index "${index} + 1")
endforeach()
file(WRITE "${OUTPUT}.tmp"
"// Generated at build time by cmake/embed_files.cmake from ${BASE}: do not edit.
#include \"status/page_files.h\"

namespace rayfarm {
namespace {
${arrays}}  // namespace

const std::vector<PageFile>& page_files() {
  static const std::vector<PageFile> files = {
${table}  };
  return files;
}

}  // namespace rayfarm
")
# Only a changed file triggers recompilation.
file(COPY_FILE "${OUTPUT}.tmp" "${OUTPUT}" ONLY_IF_DIFFERENT)
file(REMOVE "${OUTPUT}.tmp")
