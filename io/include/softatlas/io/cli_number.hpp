// Strict numbers on the command line: a CLI11 validator that takes the whole token as one finite
// number within [lo, hi] ("nan", "inf", "1e308", "-1", "12abc" are usage errors naming the option
// and the range). Header-only: include it where CLI11 is linked.
#pragma once

#include <CLI/CLI.hpp>

#include <cmath>
#include <cstdlib>
#include <sstream>
#include <string>

#include "softatlas/io/mesh_io.hpp"

namespace softatlas::io {

inline CLI::Validator finite_in(double lo, double hi) {
  std::ostringstream range;
  range << "[" << lo << ", " << hi << "]";
  const std::string desc = range.str();
  return CLI::Validator(
      [lo, hi, desc](std::string& text) -> std::string {
        char* end = nullptr;
        const double v = std::strtod(text.c_str(), &end);
        if (text.empty() || end != text.c_str() + text.size() || !std::isfinite(v))
          return "expected a finite number, got '" + printable_text(text) + "'";
        if (v < lo || v > hi) return "value " + printable_text(text) + " is outside " + desc;
        return std::string();
      },
      "FINITE in " + desc);
}

}  // namespace softatlas::io
