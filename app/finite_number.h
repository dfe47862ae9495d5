// The check for options that take a real number. CLI11's Range,
// PositiveNumber and NonNegativeNumber test `value < min || value > max`,
// which is false for NaN, so "nan" passed them all -- and a replay whose
// latency is NaN has events that never come due, and simulated forever.
#pragma once

#include <CLI/CLI.hpp>

#include <cstdio>
#include <cstdlib>
#include <limits>
#include <string>

namespace rayfarm::cmd {

// A finite number in [min, max]. A word that is no number at all is left to
// the option's conversion, which says so.
inline CLI::Validator finite_number(double min, double max = std::numeric_limits<double>::max()) {
  char text[64];
  if (max < std::numeric_limits<double>::max())
    std::snprintf(text, sizeof text, "in [%g, %g]", min, max);
  else
    std::snprintf(text, sizeof text, ">= %g", min);
  const std::string range = text;
  return CLI::Validator(
      [min, max, range](std::string& value_text) -> std::string {
        char* end = nullptr;
        const double value = std::strtod(value_text.c_str(), &end);
        if (value_text.empty() || *end != '\0') return "";
        if (value >= min && value <= max) return "";  // false for NaN, and infinity is beyond max
        return "expected a finite number " + range + ", found " + value_text;
      },
      "FLOAT " + range);
}

}  // namespace rayfarm::cmd
