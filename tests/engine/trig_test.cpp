// Deterministic trigonometry: pinned bit patterns (the whole point of trig.cpp is that these never
// change across compilers and machines), accuracy against libm, and the exact special cases.

#include "fulcrum/trig.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>

#include "fulcrum/math.h"

namespace fulcrum {
namespace {

uint64_t bits(double x) {
  uint64_t u;
  std::memcpy(&u, &x, sizeof(u));
  return u;
}

// The contract in trig.h: absolute error below 1e-15 against the true value. libm (glibc, musl,
// Apple) is within 1 ulp of the truth, i.e. within 2.2e-16 for |sin|, |cos| <= 1 and 4.4e-16 for
// atan2 near pi, so comparing against libm with the full 1e-15 bound still leaves room for
// libm's own error. (Measured: trig.cpp stays within 0.75 ulp of the truth for sin and cos and
// within 1 ulp for atan2.)
constexpr double kAbsTolerance = 1e-15;

// --- Bit-pinned values ------------------------------------------------------------------------
// These were produced by this implementation (GCC and Clang, -O0 and -O2, x86-64) and must never
// change: replays and state hashes depend on them. If one of these fails, the implementation's
// arithmetic changed (or FMA contraction crept in), not merely its accuracy.

TEST(TrigTest, SinCosBitPatternsArePinned) {
  EXPECT_EQ(bits(det_sin(0.5)), 0x3fdeaee8744b05f0u);
  EXPECT_EQ(bits(det_cos(0.5)), 0x3fec1528065b7d50u);
  EXPECT_EQ(bits(det_sin(1.0)), 0x3feaed548f090ceeu);
  EXPECT_EQ(bits(det_cos(1.0)), 0x3fe14a280fb5068cu);
  EXPECT_EQ(bits(det_sin(-2.5)), 0xbfe326af0dcfcab0u);
  EXPECT_EQ(bits(det_cos(-2.5)), 0xbfe9a2f7ef858b7du);
  EXPECT_EQ(bits(det_sin(10.0)), 0xbfe1689ef5f34f52u);
  EXPECT_EQ(bits(det_cos(10.0)), 0xbfead9ac890c6b1fu);
  EXPECT_EQ(bits(det_sin(123456.789)), 0xbfeff50e60ab53f9u);
  EXPECT_EQ(bits(det_cos(123456.789)), 0x3faa74d27c41b22au);
  EXPECT_EQ(bits(det_sin(1e6)), 0xbfd6664b2568d867u);
  EXPECT_EQ(bits(det_cos(1e6)), 0x3fedf9df9906d32cu);
}

TEST(TrigTest, Atan2BitPatternsArePinned) {
  EXPECT_EQ(bits(det_atan2(1.0, 2.0)), 0x3fddac670561bb4fu);
  EXPECT_EQ(bits(det_atan2(-3.0, -4.0)), 0xc003fc176b7a8560u);
  EXPECT_EQ(bits(det_atan2(0.1, -7.0)), 0x400904ba0292380fu);
  EXPECT_EQ(bits(det_atan2(5.0, 0.25)), 0x3ff8555a2787981fu);
}

TEST(TrigTest, SinCosAgreesWithSeparateCalls) {
  // det_sin and det_cos are the two halves of det_sincos: bit-identical, not merely close.
  for (double x : {-7.25, -1.0, 0.3, 2.0, 1e5 + 0.125}) {
    SinCos sc = det_sincos(x);
    EXPECT_EQ(bits(sc.sin), bits(det_sin(x))) << x;
    EXPECT_EQ(bits(sc.cos), bits(det_cos(x))) << x;
  }
}

// --- Accuracy ---------------------------------------------------------------------------------

TEST(TrigTest, SinCosMatchLibmOnDenseSweep) {
  // 2,000,001 points over [-100, 100], step 1e-4: about 30 periods, every quadrant many times.
  double max_sin = 0.0;
  double max_cos = 0.0;
  for (int i = -1000000; i <= 1000000; ++i) {
    double x = i * 1e-4;
    SinCos sc = det_sincos(x);
    max_sin = std::max(max_sin, std::fabs(sc.sin - std::sin(x)));
    max_cos = std::max(max_cos, std::fabs(sc.cos - std::cos(x)));
  }
  EXPECT_LE(max_sin, kAbsTolerance);
  EXPECT_LE(max_cos, kAbsTolerance);
}

TEST(TrigTest, SinCosMatchLibmOnSparseSweepToOneMillion) {
  // 200,001 points over [-1e6, 1e6] with an irrational-looking step so they land at all phases.
  // Range reduction is exact here (|k| < 2^20), so the same 1e-15 bound holds.
  double max_err = 0.0;
  for (int i = -100000; i <= 100000; ++i) {
    double x = i * 9.999999317;
    SinCos sc = det_sincos(x);
    max_err = std::max(max_err, std::fabs(sc.sin - std::sin(x)));
    max_err = std::max(max_err, std::fabs(sc.cos - std::cos(x)));
  }
  EXPECT_LE(max_err, kAbsTolerance);
  // The ends of the documented range and near multiples of pi/2, where reduction cancels most.
  for (double x : {1e6, -1e6, 999999.5, 710.0 * kPi, 355.0, 1e6 * kPi / 4.0, 0.5 * kPi, 4 * kPi}) {
    EXPECT_NEAR(det_sin(x), std::sin(x), kAbsTolerance) << x;
    EXPECT_NEAR(det_cos(x), std::cos(x), kAbsTolerance) << x;
  }
}

TEST(TrigTest, PythagoreanIdentity) {
  // sin^2 + cos^2 = 1. Each of sin and cos is within 0.75 ulp (0.83e-16) of the truth, which
  // moves the sum by at most 2 (|s| + |c|) 0.83e-16 <= 2.4e-16; evaluating s*s + c*c rounds a
  // little more. 4e-16 covers both; a systematic kernel error would show up far above it.
  double worst = 0.0;
  for (int i = -200000; i <= 200000; ++i) {
    double x = i * 0.000731 * (1 + (i & 7));
    SinCos sc = det_sincos(x);
    worst = std::max(worst, std::fabs(sc.sin * sc.sin + sc.cos * sc.cos - 1.0));
  }
  EXPECT_LE(worst, 4e-16);
}

TEST(TrigTest, Atan2MatchesLibm) {
  double max_err = 0.0;
  // A 801 x 801 grid over [-10, 10]^2 (offset so it also avoids exact zeros) ...
  for (int i = -400; i <= 400; ++i) {
    for (int j = -400; j <= 400; ++j) {
      double y = i * 0.025 + 1e-3;
      double x = j * 0.025 - 7e-4;
      max_err = std::max(max_err, std::fabs(det_atan2(y, x) - std::atan2(y, x)));
    }
  }
  // ... and very different magnitudes, where the ratio is tiny or huge.
  for (double scale : {1e-300, 1e-20, 1e-8, 1.0, 1e8, 1e20, 1e300}) {
    for (double y : {-3.0, -1e-9, 0.7, 2.0}) {
      for (double x : {-5.0, -1e-7, 1e-12, 0.3, 9.0}) {
        max_err = std::max(max_err, std::fabs(det_atan2(y * scale, x) - std::atan2(y * scale, x)));
        max_err = std::max(max_err, std::fabs(det_atan2(y, x * scale) - std::atan2(y, x * scale)));
      }
    }
  }
  EXPECT_LE(max_err, kAbsTolerance);
}

TEST(TrigTest, Atan2SmallAnglesKeepRelativeAccuracy) {
  // For tiny angles the absolute bound says little; the result must still be ~ y / x.
  EXPECT_DOUBLE_EQ(det_atan2(1e-200, 1.0), 1e-200);
  EXPECT_DOUBLE_EQ(det_atan2(-3e-12, 2.0), std::atan2(-3e-12, 2.0));
}

// --- Exact and special cases ------------------------------------------------------------------

TEST(TrigTest, ExactValues) {
  EXPECT_EQ(det_sin(0.0), 0.0);
  EXPECT_EQ(det_cos(0.0), 1.0);
  EXPECT_TRUE(std::signbit(det_sin(-0.0)));  // like libm
  // Axis cases are exact: the offsets are the correctly rounded pi, pi/2 and pi/4.
  EXPECT_EQ(det_atan2(0.0, 1.0), 0.0);
  EXPECT_EQ(det_atan2(1.0, 0.0), kPi / 2);
  EXPECT_EQ(det_atan2(0.0, -1.0), kPi);
  EXPECT_EQ(det_atan2(-1.0, 0.0), -kPi / 2);
  EXPECT_EQ(det_atan2(0.0, 0.0), 0.0);
  EXPECT_EQ(det_atan2(7.5, 0.0), kPi / 2);
  EXPECT_EQ(det_atan2(0.0, 1e-300), 0.0);
  EXPECT_EQ(det_atan2(1.0, 1.0), kPi / 4);
  EXPECT_EQ(det_atan2(-2.0, -2.0), std::atan2(-2.0, -2.0));  // -3pi/4, correctly rounded
  // Zero signs are ignored so the range is (-pi, pi]: a rotation by pi is never reported as -pi.
  EXPECT_EQ(det_atan2(-0.0, -1.0), kPi);
  EXPECT_EQ(det_atan2(-0.0, 0.0), 0.0);
  EXPECT_EQ(det_atan2(0.0, -0.0), 0.0);
}

TEST(TrigTest, NonFiniteInputGivesNaN) {
  const double inf = std::numeric_limits<double>::infinity();
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_TRUE(std::isnan(det_sin(nan)));
  EXPECT_TRUE(std::isnan(det_cos(inf)));
  SinCos sc = det_sincos(-inf);
  EXPECT_TRUE(std::isnan(sc.sin));
  EXPECT_TRUE(std::isnan(sc.cos));
  EXPECT_TRUE(std::isnan(det_atan2(nan, 1.0)));
  EXPECT_TRUE(std::isnan(det_atan2(1.0, nan)));
  EXPECT_TRUE(std::isnan(det_atan2(inf, 1.0)));
  EXPECT_TRUE(std::isnan(det_atan2(0.0, -inf)));
}

TEST(TrigTest, HugeArgumentsStayBoundedAndDeterministic) {
  // Beyond 1e6 accuracy is not promised, but the values must be a point on the unit circle
  // (the kernels only ever see |r| <= pi/4) and repeatable.
  for (double x : {3e6, 1e15, -1e100, 1e300, std::numeric_limits<double>::max()}) {
    SinCos a = det_sincos(x);
    SinCos b = det_sincos(x);
    EXPECT_EQ(bits(a.sin), bits(b.sin));
    EXPECT_EQ(bits(a.cos), bits(b.cos));
    EXPECT_NEAR(a.sin * a.sin + a.cos * a.cos, 1.0, 4e-16) << x;
  }
  // Up to 2^20 pi/2 (~1.6e6) the reduction is still exact, so libm agreement continues a little
  // past the documented range.
  EXPECT_NEAR(det_sin(1.5e6), std::sin(1.5e6), kAbsTolerance);
}

// --- Rot --------------------------------------------------------------------------------------

TEST(TrigTest, RotFromAngleAndBack) {
  Rot identity = Rot::from_angle(0.0);
  EXPECT_EQ(identity.c, 1.0);
  EXPECT_EQ(identity.s, 0.0);
  EXPECT_EQ(identity.angle(), 0.0);
  EXPECT_EQ((Rot{-1.0, 0.0}).angle(), kPi);

  // For angles in (-pi, pi], from_angle then angle returns the input: sin and cos carry ~1e-16
  // errors that move the recovered angle by about as much, and atan2 adds at most an ulp of the
  // result (4.4e-16 near pi). 1e-15 is the documented atan2 bound and covers the sum.
  double worst = 0.0;
  for (int i = -3141; i <= 3141; ++i) {
    double a = i * 1e-3;
    Rot q = Rot::from_angle(a);
    EXPECT_EQ(q.c, det_cos(a));
    EXPECT_EQ(q.s, det_sin(a));
    worst = std::max(worst, std::fabs(q.angle() - a));
  }
  EXPECT_LE(worst, 1e-15);

  // Outside (-pi, pi] the angle wraps to the same direction. Compared with libm's view of that
  // direction, with the same 1e-15 bound (the argument is one double, so no rounding of the
  // input enters).
  for (double a : {0.4 + 6.0 * kPi, -0.4 - 2.0 * kPi, 100.0, -2500.5}) {
    EXPECT_NEAR(Rot::from_angle(a).angle(), std::atan2(std::sin(a), std::cos(a)), 1e-15) << a;
  }
}

}  // namespace
}  // namespace fulcrum
