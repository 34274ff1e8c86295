// Per-step solver data: compact body states and contact constraint rows, rebuilt each step from
// the awake set. Kept in the world only to reuse allocations.
#pragma once

#include <vector>

#include "fulcrum/math.h"

namespace fulcrum {

// What the iterations touch per body.
struct SolverBody {
  Vec2 v = Vec2::Zero();  // velocity of the centre of mass
  double w = 0.0;
  double inv_mass = 0.0;
  Vec2 dp = Vec2::Zero();  // displacement of the centre of mass since the tick began
  Rot dq;                  // rotation since the tick began
  Vec2 pv = Vec2::Zero();  // pseudo velocity (split impulses): moves positions only
  double pw = 0.0;
  double inv_inertia = 0.0;
};

// Soft constraint coefficients for one substep (Catto, "Solver2D", 2024): a spring of
// stiffness omega = 2 pi hertz with damping ratio zeta, made implicit. The row impulse becomes
//   lambda = -m_c mass_scale (J v + bias_rate C) - impulse_scale * accumulated.
// Rigid rows have bias_rate 0, mass_scale 1, impulse_scale 0.
struct Softness {
  double bias_rate = 0.0;
  double mass_scale = 1.0;
  double impulse_scale = 0.0;
};

struct ContactPointRow {
  Vec2 ra = Vec2::Zero();  // contact point relative to body A's centre of mass (tick start)
  Vec2 rb = Vec2::Zero();
  double base_separation = 0.0;  // separation minus n . (rb - ra): current separation is
                                 // n . (moved anchor B - moved anchor A) + this
  double normal_mass = 0.0;      // 1 / (J M^-1 J^T) for the normal row
  double tangent_mass = 0.0;     // the same for the friction row
  double normal_impulse = 0.0;   // accumulated
  double tangent_impulse = 0.0;  // accumulated
  double pseudo_impulse = 0.0;   // accumulated, on pseudo velocities
  double max_normal_impulse = 0.0;
  double approach_speed = 0.0;  // normal relative velocity at impact (restitution)
  double speed_before = 0.0;    // normal relative velocity before this substep's forces
};

struct ContactRow {
  int contact = -1;
  int ia = 0, ib = 0;  // solver body slots (0: the shared static body)
  Vec2 normal = Vec2::Zero();
  double friction = 0.0;
  double restitution = 0.0;
  int count = 0;
  bool block = false;  // rigid mode: solve both normal rows together
  Softness softness;
  Mat22 k;  // 2x2 effective-mass matrix of the normal rows
  Mat22 k_inverse;
  ContactPointRow points[2];
};

struct SolverScratch {
  std::vector<SolverBody> bodies;
  std::vector<int> body_slot;  // body index -> solver slot (0 for bodies not solved)
  std::vector<ContactRow> rows;
  std::vector<int> contacts;
};

}  // namespace fulcrum
