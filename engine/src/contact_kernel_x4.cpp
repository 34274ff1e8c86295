// The 4-lane contact path. On x86-64 this file alone is built with -mavx2 (and never -mfma) and
// runs only when the CPU has AVX2; elsewhere it is built for the baseline, where the compiler
// splits each vector operation into narrower ones with the same per-lane results.
// contact_kernel_x4e.cpp builds the same functions again, named *_x4e, for AVX-512F and VL.
#define FULCRUM_CONTACT_LANES4 1
#include "contact_kernel.h"
#include "joint_kernel.h"

#ifndef FULCRUM_X4_NAME
#define FULCRUM_X4_NAME(base) base##_x4
#endif

namespace fulcrum::lanes {

double FULCRUM_X4_NAME(solve)(ContactBlock* blocks, int first, int end, SolverBody* bodies,
                              const LaneRule& rule) {
  return solve_blocks<LanePair<F64x4>>(blocks, first, end, bodies, rule);
}

void FULCRUM_X4_NAME(warm)(ContactBlock* blocks, int first, int end, SolverBody* bodies) {
  warm_blocks<LanePair<F64x4>>(blocks, first, end, bodies);
}

void FULCRUM_X4_NAME(separation)(ContactBlock* blocks, const ContactBlockRest* rests, int first,
                                 int end, const SolverBody* bodies) {
  separation_blocks<F64x4>(blocks, rests, first, end, bodies);
}

void FULCRUM_X4_NAME(approach)(const ContactBlock* blocks, ContactBlockRest* rests,
                               const int* which, int first, int end, const SolverBody* bodies,
                               const VelocityBefore* before, double inv_h) {
  approach_blocks<F64x4>(blocks, rests, which, first, end, bodies, before, inv_h);
}

void FULCRUM_X4_NAME(integrate)(SolverBody* bodies, SolverBodyExtra* extras,
                                const IntegrateRule& rule, int first, int end) {
  // Eight bodies at a time: each body's chain of a square root and a division (the rotation
  // renormalized) is long, and two groups of four run it side by side.
  integrate_bodies<LanePair<F64x4>>(bodies, extras, rule, first, end);
}

void FULCRUM_X4_NAME(solve_points)(PointBlock* blocks, int first, int end, SolverBody* bodies,
                                   const PointRule& rule) {
  solve_point_blocks<F64x4>(blocks, first, end, bodies, rule);
}

void FULCRUM_X4_NAME(warm_points)(PointBlock* blocks, int first, int end, SolverBody* bodies) {
  warm_point_blocks<F64x4>(blocks, first, end, bodies);
}

void FULCRUM_X4_NAME(solve_revolutes)(RevoluteBlock* blocks, int first, int end, SolverBody* bodies,
                                      const SolverBodyExtra* extras, const PointRule& rule) {
  solve_revolute_blocks<F64x4>(blocks, first, end, bodies, extras, rule);
}

void FULCRUM_X4_NAME(warm_revolutes)(RevoluteBlock* blocks, int first, int end,
                                     SolverBody* bodies) {
  warm_revolute_blocks<F64x4>(blocks, first, end, bodies);
}

}  // namespace fulcrum::lanes
