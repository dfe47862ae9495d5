// What every rayfarm fuzz target checks beyond "no crash, no sanitizer
// report": bad input must end in an InputError whose message starts with the
// name of the input (the file, key path or field it names comes after), never
// in any other exception. A violation aborts, which libFuzzer records as a
// crash with the input that caused it.
#pragma once

#include <cstdio>
#include <cstdlib>
#include <string>
#include <string_view>

#include "tracer/error.h"

namespace rayfarm::fuzz {

[[noreturn]] inline void fail(const std::string& why) {
  std::fprintf(stderr, "fuzz oracle: %s\n", why.c_str());
  std::abort();
}

// Runs `parse()`; an InputError must name `where` first.
template <class Parse>
void expect_clean_error(std::string_view where, Parse&& parse) {
  try {
    parse();
  } catch (const InputError& e) {
    const std::string_view what = e.what();
    if (what.substr(0, where.size()) != where) fail("error does not start with \"" + std::string(where) + "\": " + std::string(what));
  }
}

}  // namespace rayfarm::fuzz
