// Wall-clock seconds since a steady_clock time point: how every phase time in
// stats, job records and row-cost profiles is taken.
#pragma once

#include <chrono>

namespace rayfarm {

inline double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace rayfarm
