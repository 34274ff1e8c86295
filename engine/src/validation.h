// Range checks for user input. Each returns an error naming `field`, the rule and the value
// when the value breaks the rule; written as !(ok) so that NaN fails every check.
#pragma once

#include <cmath>
#include <cstdio>
#include <string>

#include "fulcrum/math.h"
#include "fulcrum/status.h"

namespace fulcrum {

// Shortest text that reads back as the same double.
inline std::string format_number(double x) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.17g", x);
  return buf;
}

inline Status check_finite(const std::string& field, double x) {
  if (!std::isfinite(x)) {
    return invalid_argument(field + ": must be finite (got " + format_number(x) + ")");
  }
  return {};
}

inline Status check_finite(const std::string& field, const Vec2& v) {
  if (!is_finite(v)) {
    return invalid_argument(field + ": must be finite (got (" + format_number(v.x()) + ", " +
                            format_number(v.y()) + "))");
  }
  return {};
}

inline Status check_above(const std::string& field, double x, double lo) {
  if (!(x > lo) || !std::isfinite(x)) {
    return invalid_argument(field + ": must be finite and > " + format_number(lo) + " (got " +
                            format_number(x) + ")");
  }
  return {};
}

inline Status check_non_negative(const std::string& field, double x) {
  if (!(x >= 0.0) || !std::isfinite(x)) {
    return invalid_argument(field + ": must be finite and >= 0 (got " + format_number(x) + ")");
  }
  return {};
}

inline Status check_in_range(const std::string& field, double x, double lo, double hi) {
  if (!(x >= lo && x <= hi)) {
    return invalid_argument(field + ": must be in [" + format_number(lo) + ", " +
                            format_number(hi) + "] (got " + format_number(x) + ")");
  }
  return {};
}

}  // namespace fulcrum
