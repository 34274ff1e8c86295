// Range checks for user input. Each returns an error naming `field`, the rule and the value
// when the value breaks the rule; written as !(ok) so that NaN fails every check.
#pragma once

#include <cmath>
#include <cstdio>
#include <string>

#include "fulcrum/geometry.h"
#include "fulcrum/math.h"
#include "fulcrum/status.h"

namespace fulcrum {

// Shortest text that reads back as the same double.
inline std::string format_number(double x) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.17g", x);
  return buf;
}

inline std::string magnitude_rule() {
  static_assert(kMaxInputMagnitude == 1e12, "the text below names the bound");
  return "at most 1e12 in magnitude";
}

// Finite and within kMaxInputMagnitude (fulcrum/types.h).
inline Status check_finite(const std::string& field, double x) {
  if (!std::isfinite(x)) {
    return invalid_argument(field + ": must be finite (got " + format_number(x) + ")");
  }
  if (!(std::fabs(x) <= kMaxInputMagnitude)) {
    return invalid_argument(field + ": must be " + magnitude_rule() + " (got " + format_number(x) +
                            ")");
  }
  return {};
}

inline Status check_finite(const std::string& field, const Vec2& v) {
  // The value is formatted only for the message: a valid vector costs two comparisons (world
  // building checks every body's, shape's and joint's vectors).
  auto got = [&] { return "(got (" + format_number(v.x()) + ", " + format_number(v.y()) + "))"; };
  if (!is_finite(v)) return invalid_argument(field + ": must be finite " + got());
  if (!(std::fabs(v.x()) <= kMaxInputMagnitude && std::fabs(v.y()) <= kMaxInputMagnitude)) {
    return invalid_argument(field + ": each coordinate must be " + magnitude_rule() + " " + got());
  }
  return {};
}

inline Status check_above(const std::string& field, double x, double lo) {
  if (!(x > lo) || !std::isfinite(x)) {
    return invalid_argument(field + ": must be finite and > " + format_number(lo) + " (got " +
                            format_number(x) + ")");
  }
  return check_finite(field, x);
}

inline Status check_non_negative(const std::string& field, double x) {
  if (!(x >= 0.0) || !std::isfinite(x)) {
    return invalid_argument(field + ": must be finite and >= 0 (got " + format_number(x) + ")");
  }
  return check_finite(field, x);
}

// A bound the solver clamps an impulse to (a motor's or a motor joint's greatest force or
// torque): any finite value >= 0. It only ever limits, so no size of it can overflow a product.
inline Status check_cap(const std::string& field, double x) {
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
