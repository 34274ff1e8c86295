// The 4-lane contact path. On x86-64 this file alone is built with -mavx2 (and never -mfma) and
// runs only when the CPU has AVX2; elsewhere it is built for the baseline, where the compiler
// splits each vector operation into narrower ones with the same per-lane results.
#define FULCRUM_CONTACT_LANES4 1
#include "contact_kernel.h"
#include "joint_kernel.h"

namespace fulcrum::lanes {

double solve_x4(ContactBlock* blocks, int first, int end, SolverBody* bodies,
                const LaneRule& rule) {
  return solve_blocks<LanePair<F64x4>>(blocks, first, end, bodies, rule);
}

void warm_x4(ContactBlock* blocks, int first, int end, SolverBody* bodies) {
  warm_blocks<LanePair<F64x4>>(blocks, first, end, bodies);
}

void separation_x4(ContactBlock* blocks, int first, int end, const SolverBody* bodies) {
  separation_blocks<F64x4>(blocks, first, end, bodies);
}

void solve_points_x4(PointBlock* blocks, int first, int end, SolverBody* bodies,
                     const PointRule& rule) {
  solve_point_blocks<F64x4>(blocks, first, end, bodies, rule);
}

void warm_points_x4(PointBlock* blocks, int first, int end, SolverBody* bodies) {
  warm_point_blocks<F64x4>(blocks, first, end, bodies);
}

}  // namespace fulcrum::lanes
