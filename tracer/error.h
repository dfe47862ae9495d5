// InputError: bad input from outside (scene files, configs, command lines,
// network peers), reported with the place it was found, e.g.
// "scene.nff:12: expected 4 numbers after 's'". Our own invariants use assert.
#pragma once

#include <stdexcept>
#include <string>

namespace rayfarm {

struct InputError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

}  // namespace rayfarm
