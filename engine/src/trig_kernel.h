// The polynomial kernels of det_sin and det_cos on [-pi/4, pi/4] (trig.cpp), written once over
// a number type T: double, or a GCC/Clang vector of doubles, on which every lane performs the
// scalar operations in the same order (contact_kernel.h integrates body rotations so, with the
// same bits as det_sincos). Internal linkage: the copies built for different instruction sets
// never merge.
#pragma once

namespace fulcrum {
namespace {

// --- Kernels on [-pi/4, pi/4] -----------------------------------------------------------------
//
// det_sincos reduces |x| > kPio4 to that range first; smaller arguments reach the kernels as
// they are, with y = 0.
constexpr double kPio4 = 0.7853981633974483;
//
//
// Taylor series, truncated where the next term is below 1e-19 at |r| = pi/4:
//   sin r = r - r^3/3! + r^5/5! - ... + r^17/17!   (next term r^19/19! ~ 8e-20)
//   cos r = 1 - r^2/2! + r^4/4! - ... + r^18/18!   (next term r^20/20! ~ 3e-21)
// The argument arrives as hi + lo; to first order sin(hi + lo) = sin hi + lo cos hi and
// cos(hi + lo) = cos hi - lo sin hi, with cos hi ~ 1 - hi^2/2 and sin hi ~ hi.
constexpr double kSin3 = -0.16666666666666666;
constexpr double kSin5 = 0.008333333333333333;
constexpr double kSin7 = -0.0001984126984126984;
constexpr double kSin9 = 2.7557319223985893e-06;
constexpr double kSin11 = -2.505210838544172e-08;
constexpr double kSin13 = 1.6059043836821613e-10;
constexpr double kSin15 = -7.647163731819816e-13;
constexpr double kSin17 = 2.8114572543455206e-15;

constexpr double kCos4 = 0.041666666666666664;
constexpr double kCos6 = -0.001388888888888889;
constexpr double kCos8 = 2.48015873015873e-05;
constexpr double kCos10 = -2.755731922398589e-07;
constexpr double kCos12 = 2.08767569878681e-09;
constexpr double kCos14 = -1.1470745597729725e-11;
constexpr double kCos16 = 4.779477332387385e-14;
constexpr double kCos18 = -1.5619206968586225e-16;

template <class T>
T kernel_sin(T x, T y) {
  T z = x * x;
  T v = z * x;
  // sin x = x + x^3 (-1/3!) + x^5 p(z) with p(z) = 1/5! - z/7! + ... + z^6/17!.
  T p = kSin5 + z * (kSin7 + z * (kSin9 + z * (kSin11 + z * (kSin13 + z * (kSin15 + z * kSin17)))));
  // Everything but x is small (|.| < 0.09), so it is summed first and x is added last, once.
  T correction = v * kSin3 + (v * z * p + y * (1.0 - 0.5 * z));
  return x + correction;
}

template <class T>
T kernel_cos(T x, T y) {
  T z = x * x;
  T p = kCos4 +
        z * (kCos6 +
             z * (kCos8 + z * (kCos10 + z * (kCos12 + z * (kCos14 + z * (kCos16 + z * kCos18))))));
  T hz = 0.5 * z;
  T w = 1.0 - hz;
  // 1 - w is exact (Sterbenz, w in [0.69, 1]), so (1 - w) - hz recovers the rounding error of
  // w exactly and feeds it back in together with the small terms.
  return w + (((1.0 - w) - hz) + (z * z * p - x * y));
}

}  // namespace
}  // namespace fulcrum
