// The shared body of the config fuzz targets (worker config, broker config,
// lab): the loader gets arbitrary bytes as JSON text named `name`, and must
// return a config or throw InputError "name: key.path: reason".
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

#include "fuzz/fuzz_oracle.h"

namespace rayfarm::fuzz {

template <class Parse>
int check_config_input(const uint8_t* data, size_t size, const std::string& name, Parse&& parse) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  expect_clean_error(name + ": ", [&] { parse(text, name); });
  return 0;
}

}  // namespace rayfarm::fuzz
