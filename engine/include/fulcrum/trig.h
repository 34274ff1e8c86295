// Deterministic trigonometry. libm's sin/cos/atan2 differ between C libraries and CPUs in the
// last bit, which would break bit-exact replays; these use only IEEE-exact operations (+, -, *,
// /, sqrt) in a fixed order, so every build and machine gets the same bits.
#pragma once

namespace fulcrum {

struct SinCos {
  double sin;
  double cos;
};

// sin and cos of x (radians). Absolute error below 1e-15 for |x| <= 1e6; any finite input is
// accepted (huge arguments lose accuracy through range reduction, never determinism).
SinCos det_sincos(double x);
double det_sin(double x);
double det_cos(double x);
// atan2(y, x) in [-pi, pi], absolute error below 1e-15. atan2(0, 0) is 0.
double det_atan2(double y, double x);

inline constexpr double kPi = 3.14159265358979323846;

}  // namespace fulcrum
