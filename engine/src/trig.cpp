// Deterministic sin, cos and atan2 built only from IEEE 754 operations that are correctly
// rounded everywhere (+, -, *, /, floor), evaluated in a fixed order. The engine is compiled
// with -ffp-contract=off, so no multiply-add is fused behind our back.
//
// Constants were computed offline with 400-bit arithmetic (mpmath) and are written as the
// shortest decimal that round-trips to the intended double.

#include "fulcrum/trig.h"

#include <cmath>
#include <limits>

#include "fulcrum/math.h"
#include "trig_kernel.h"

namespace fulcrum {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// --- Range reduction --------------------------------------------------------------------------
//
// x = k * (pi/2) + r with k = round(x * 2/pi) and |r| <= pi/4 (plus a rounding hair).
// pi/2 is split Cody-Waite style into P1 + P2 + P3 where P1 and P2 hold 33 significant bits
// each, so k * P1 and k * P2 are exact while |k| < 2^20, and x - k * P1 is exact by Sterbenz's
// lemma. |pi/2 - (P1 + P2 + P3)| ~ 1e-37, so for |x| <= 1e6 the reduction error is ~1e-31.
constexpr double kTwoOverPi = 0.6366197723675814;
constexpr double kPio2Part1 = 1.5707963267341256;     // 0x1.921fb544p+0, 33 bits
constexpr double kPio2Part2 = 6.077100506303966e-11;  // 0x1.0b4611a6p-34, 33 bits
constexpr double kPio2Part3 = 2.0222662487959506e-21;
// Largest |k| for which k * P1 and k * P2 are exact (53 - 33 = 20 spare bits).
constexpr double kExactReductionLimit = 1048576.0;  // 2^20

// a + b = s + e exactly (Knuth's TwoSum; no ordering precondition on |a|, |b|).
inline void two_sum(double a, double b, double* s, double* e) {
  double sum = a + b;
  double bv = sum - a;
  double av = sum - bv;
  *s = sum;
  *e = (a - av) + (b - bv);
}

// a * b = p + e exactly (Dekker's product: split each factor into 26-bit halves whose
// products are exact). Valid while |a|, |b| < ~1e300 so the splitting cannot overflow.
inline void two_prod(double a, double b, double* p, double* e) {
  constexpr double kSplit = 134217729.0;  // 2^27 + 1
  double ca = kSplit * a;
  double a_hi = ca - (ca - a);
  double a_lo = a - a_hi;
  double cb = kSplit * b;
  double b_hi = cb - (cb - b);
  double b_lo = b - b_hi;
  double prod = a * b;
  *p = prod;
  *e = ((a_hi * b_hi - prod) + a_hi * b_lo + a_lo * b_hi) + a_lo * b_lo;
}

// k mod 4 for an integral double k, as 0..3. floor(k / 4) is exact for integral k (division
// by a power of two), so the remainder is exact at any magnitude.
inline int quadrant_of(double k) {
  double m = k - 4.0 * std::floor(k * 0.25);
  return static_cast<int>(m);
}

struct Reduced {
  double hi;     // r ~ hi + lo
  double lo;     // a few ulp of hi at most
  int quadrant;  // k mod 4
};

// Reduces a finite x to r in about [-pi/4, pi/4] and its quadrant.
Reduced reduce_pio2(double x) {
  Reduced out{x, 0.0, 0};
  if (std::fabs(x) <= kPio4) return out;

  double r = x;
  int quadrant = 0;
  // Arguments beyond 2^20 * pi/2 (~1.6e6) cannot be reduced exactly with this split. Each
  // inexact pass still shrinks |r| by a factor of at least ~2^34 (the size of P2 relative to
  // P1), so a few passes bring any finite double down to the exact range. The result is
  // meaningless as an angle there, but it is bounded and deterministic.
  for (int pass = 0; pass < 64; ++pass) {
    double k = std::floor(r * kTwoOverPi + 0.5);
    if (std::fabs(k) < kExactReductionLimit) break;
    quadrant = (quadrant + quadrant_of(k)) & 3;
    r = ((r - k * kPio2Part1) - k * kPio2Part2) - k * kPio2Part3;
  }

  double k = std::floor(r * kTwoOverPi + 0.5);
  quadrant = (quadrant + quadrant_of(k)) & 3;
  // r1 = r - k P1 is exact; r1 - k P2 is tracked as a double-double; k P3 is tiny.
  double r1 = r - k * kPio2Part1;
  double w1 = k * kPio2Part2;
  double r2;
  double e2;
  two_sum(r1, -w1, &r2, &e2);
  double tail = e2 - k * kPio2Part3;
  two_sum(r2, tail, &out.hi, &out.lo);
  out.quadrant = quadrant;
  return out;
}

// --- atan on [0, 1] ---------------------------------------------------------------------------
//
// atan t = atan c + atan u with u = (t - c) / (1 + t c), where c = j/8 is a breakpoint and atan c
// is tabulated as hi + lo. Below t = 1/8 no breakpoint is used (c = 0, u = t); otherwise c is
// the breakpoint nearest to t from below or above. Taking c = 1/8 for t < 1/8 would make
// atan c and atan u cancel and cost accuracy relative to the small result.
// Hence |u| <= 1/8, and the Taylor series u - u^3/3 + ... - u^19/19 has a remainder below
// |u| * u^20/21 ~ |u| 2^-64, far under an ulp.
constexpr double kAtanHi[9] = {
    0.0,
    0.12435499454676144,
    0.24497866312686414,
    0.35877067027057225,
    0.4636476090008061,
    0.5585993153435624,
    0.6435011087932844,
    0.7188299996216245,
    0.7853981633974483,
};
constexpr double kAtanLo[9] = {
    0.0,
    -3.1253241424539383e-18,
    1.0698755618734451e-17,
    -2.4623815582638635e-17,
    2.2698777452961687e-17,
    -5.4556305485916264e-18,
    1.5834785051444286e-17,
    -2.1478388444456983e-17,
    3.061616997868383e-17,
};
constexpr double kAtan3 = -0.3333333333333333;
constexpr double kAtan5 = 0.2;
constexpr double kAtan7 = -0.14285714285714285;
constexpr double kAtan9 = 0.1111111111111111;
constexpr double kAtan11 = -0.09090909090909091;
constexpr double kAtan13 = 0.07692307692307693;
constexpr double kAtan15 = -0.06666666666666667;
constexpr double kAtan17 = 0.058823529411764705;
constexpr double kAtan19 = -0.05263157894736842;

constexpr double kPiHi = 3.141592653589793;
constexpr double kPiLo = 1.2246467991473532e-16;
constexpr double kPio2Hi = 1.5707963267948966;
constexpr double kPio2Lo = 6.123233995736766e-17;

// atan(t + t_lo) for t in [0, 1] and a tiny t_lo, as hi + lo, where hi is a table entry and
// lo is the rest. To first order atan(t + t_lo) = atan t + t_lo / (1 + t^2).
void atan_unit(double t, double t_lo, double* hi, double* lo) {
  int j = t < 0.125 ? 0 : static_cast<int>(std::floor(t * 8.0 + 0.5));
  double c = 0.125 * j;
  // t - c is exact: c = 0, or t is in [c - 1/16, c + 1/16] with c >= 1/8, within a factor of 2.
  double u = (t - c) / (1.0 + t * c);
  double z = u * u;
  double p =
      kAtan3 +
      z * (kAtan5 +
           z * (kAtan7 +
                z * (kAtan9 +
                     z * (kAtan11 + z * (kAtan13 + z * (kAtan15 + z * (kAtan17 + z * kAtan19)))))));
  *hi = kAtanHi[j];
  *lo = kAtanLo[j] + (u + (u * z * p + t_lo / (1.0 + t * t)));
}

}  // namespace

SinCos det_sincos(double x) {
  if (!std::isfinite(x)) return SinCos{kNaN, kNaN};
  // Keeps the sign of zero like libm: sin(-0) = -0.
  if (x == 0.0) return SinCos{x, 1.0};
  Reduced r = reduce_pio2(x);
  double s = kernel_sin(r.hi, r.lo);
  double c = kernel_cos(r.hi, r.lo);
  // sin(k pi/2 + r) and cos(k pi/2 + r) by quadrant.
  switch (r.quadrant) {
    case 0:
      return SinCos{s, c};
    case 1:
      return SinCos{c, -s};
    case 2:
      return SinCos{-s, -c};
    default:
      return SinCos{-c, s};
  }
}

double det_sin(double x) {
  return det_sincos(x).sin;
}

double det_cos(double x) {
  return det_sincos(x).cos;
}

// atan2(y, x) in (-pi, pi]. Signs of zero are ignored (a zero y counts as +0), so the axis
// cases are exact and -pi is never returned: atan2(0, x > 0) = 0, atan2(0, x < 0) = pi,
// atan2(+-y, 0) = +-pi/2 and atan2(0, 0) = 0. Non-finite input gives NaN.
double det_atan2(double y, double x) {
  if (!std::isfinite(x) || !std::isfinite(y)) return kNaN;
  double ax = std::fabs(x);
  double ay = std::fabs(y);
  if (ay == 0.0) return x < 0.0 ? kPiHi : 0.0;

  // The smaller over the larger, so t is in [0, 1] and never overflows.
  bool steep = ay > ax;
  double num = steep ? ax : ay;
  double den = steep ? ay : ax;
  double t = num / den;
  // The quotient's rounding error alone would cost up to an ulp of the result. The remainder
  // num - t den is exactly representable and recovered exactly from Dekker's product, giving
  // t_lo = (num - t den) / den with num / den = t + t_lo to about 2^-106 relative. Above 1e300
  // the splitting could overflow, so the (tiny) correction is skipped there.
  double t_lo = 0.0;
  if (den < 1e300) {
    double p;
    double e;
    two_prod(t, den, &p, &e);
    t_lo = ((num - p) - e) / den;
  }
  double a_hi;
  double a_lo;
  atan_unit(t, t_lo, &a_hi, &a_lo);

  // angle = offset + sign * atan t, the offset and sign by octant:
  //   |y| <= |x|, x >= 0:  0    + a       |y| <= |x|, x < 0:  pi   - a
  //   |y| >  |x|, x >= 0:  pi/2 - a       |y| >  |x|, x < 0:  pi/2 + a
  double off_hi = 0.0;
  double off_lo = 0.0;
  double sign = 1.0;
  if (steep) {
    off_hi = kPio2Hi;
    off_lo = kPio2Lo;
    sign = x < 0.0 ? 1.0 : -1.0;
  } else if (x < 0.0) {
    off_hi = kPiHi;
    off_lo = kPiLo;
    sign = -1.0;
  }
  // The large parts are added exactly; the single final addition rounds once.
  double s;
  double e;
  two_sum(off_hi, sign * a_hi, &s, &e);
  double angle = s + (e + (off_lo + sign * a_lo));
  return y < 0.0 ? -angle : angle;
}

Rot Rot::from_angle(double radians) {
  SinCos sc = det_sincos(radians);
  return Rot{sc.cos, sc.sin};
}

double Rot::angle() const {
  return det_atan2(s, c);
}

}  // namespace fulcrum
