// The reference solver: one tick's constraint system solved to a tight tolerance, kept as the
// ruler for the iterative solver settings (MISSION.md: "We keep a global solver as the
// reference that measures the error of the fast ones"; issue 6).
//
// What it solves. From the world's state at the start of a tick, in the classic rigid form
// (one substep of dt, no softness): the applied forces are integrated into the velocities
// v0 exactly as World::step does, every active row is built from the same contact manifolds
// and joint anchors the step would use, and the velocity-level problem
//   find lambda with  w = J v + bias,  v = v0 + M^-1 J^T lambda,
//   equality rows:    w = 0
//   bounded rows:     lo <= lambda <= hi and lambda = lo => w >= 0, lambda = hi => w <= 0,
//                     lo < lambda < hi => w = 0
//   contact normal:   lo = 0, hi = inf
//   friction:         |lambda_t| <= mu lambda_n (of the same point), the same rule
//   limits:           lo = 0; motors: |lambda| <= max force (torque) x dt
// is solved for lambda; the result is v, the velocities the bodies leave the tick with.
//
// The bias. Separated rows (contact points kept within the speculative distance, limits not
// yet reached) carry bias = gap / dt, exactly as in the step: the gap may close within the
// tick, no more. Overlap and joint drift carry no bias: position feedback is a correction of
// position error, not part of the dynamics, and the velocities World::step leaves in the
// bodies are free of it in the default soft step (the relax pass removes it) and with split
// impulses (it goes to pseudo velocities). The classic step without split impulses keeps its
// Baumgarte push-out in the velocities; against this reference that push-out counts as error.
// (A Baumgarte reference was tried and left out: with it, the two friction rows of a resting
// two-point manifold, whose points lie at slightly different depths, ask for a relative motion
// the normal rows forbid, so its exact solution is a micro-slip reached only as the tangent
// impulses run apart, and no method converges to 1e-10 in reasonable time.)
//
// Restitution is not modelled (the step applies it after the iterations); use scenes without
// it, or read the velocity error of bouncing contacts as including the bounce.
#pragma once

#include <string>
#include <vector>

#include "fulcrum/math.h"
#include "fulcrum/status.h"
#include "fulcrum/types.h"
#include "fulcrum/world.h"

namespace fulcrum {

struct ReferenceOptions {
  double tolerance = 1e-10;      // N s (N m s for angular rows), > 0: residual to reach
  int max_iterations = 2000000;  // >= 1: cap on projected Gauss-Seidel sweeps
};

enum class ReferenceRowKind { kEquality, kNormal, kFriction, kBounded };

// One row's impulse at the solution. Bodies not moved by the solve (static) are null handles.
struct ReferenceImpulse {
  ReferenceRowKind kind = ReferenceRowKind::kEquality;
  BodyId body_a, body_b;
  double impulse = 0.0;  // N s (N m s for angular rows), along the row's Jacobian
};

struct ReferenceSolution {
  // The bodies solved (awake at the start of the tick, static excluded), by index, with the
  // velocities of their centres of mass after the tick's solve: what World::step would leave
  // in them (position integration does not change velocities).
  std::vector<BodyId> bodies;
  std::vector<Vec2> linear_velocity;     // m/s
  std::vector<double> angular_velocity;  // rad/s
  // Every row's impulse, in the solver's row order: joints (by id), then per contact (by id)
  // its normal rows and its friction rows.
  std::vector<ReferenceImpulse> impulses;
  // Rows by kind.
  int equality_rows = 0;  // joint rows that must hold exactly
  int normal_rows = 0;    // contact points
  int friction_rows = 0;
  int bounded_rows = 0;  // joint limits and motors
  // The residual: the largest |lambda_i - proj_i(lambda_i - m_i w_i)| over all rows, N s
  // (N m s for angular rows), with m_i = 1 / (J_i M^-1 J_i^T) and proj_i the clamp to row
  // i's bounds (friction: +-mu times the current normal impulse). It is the impulse one
  // Jacobi step would still apply: zero exactly at a solution of the problem above.
  double residual = 0.0;
  bool converged = false;    // residual <= options.tolerance
  int iterations = 0;        // projected Gauss-Seidel sweeps
  int direct_solves = 0;     // sparse LDLT solves (equality systems, active-set polishing)
  bool regularized = false;  // a singular system was met (redundant rows, see reference.cpp)
  std::string method;        // "sparse LDLT" or "projected Gauss-Seidel + active-set LDLT"
};

// The reference solution of the tick that world.step() would take next. The world is not
// changed (the solve runs on a copy). Fails, naming the joint, on rows it does not model
// (joint springs, wheel, motor, target and curve joints).
Result<ReferenceSolution> solve_reference(const World& world, const ReferenceOptions& options = {});

// The distance of a world's body velocities from a reference solution, over the reference's
// bodies: |dv| = |v - v_ref| in m/s and |dw| in rad/s, largest and root mean square over the
// bodies, not mass-weighted (every body counts the same, so that a light body thrown off by a
// heavy one shows).
struct VelocityError {
  int bodies = 0;
  double max_linear = 0.0;   // m/s
  double rms_linear = 0.0;   // m/s
  double max_angular = 0.0;  // rad/s
  double rms_angular = 0.0;  // rad/s
};
// `stepped` is the world after one step from the state the reference was solved from.
Result<VelocityError> velocity_error(const ReferenceSolution& reference, const World& stepped);

struct SettingError {
  ReferenceSolution reference;
  VelocityError error;
};
// The velocity error of a solver setting: solves the reference from `world`, steps a copy of
// `world` once with `settings` (sleeping turned off for that step, so that an island falling
// asleep does not zero the velocities being compared), and compares.
Result<SettingError> setting_velocity_error(const World& world, const WorldSettings& settings,
                                            const ReferenceOptions& options = {});

}  // namespace fulcrum
