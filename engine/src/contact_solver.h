// Per-step solver data: compact body states and contact constraint rows, rebuilt each step from
// the awake set. Kept in the world only to reuse allocations.
#pragma once

#include <vector>

#include "fulcrum/math.h"

namespace fulcrum {

// What the iterations touch per body: 64 bytes.
struct SolverBody {
  Vec2 v = Vec2::Zero();   // velocity of the centre of mass
  double w = 0.0;
  double inv_mass = 0.0;
  Vec2 pv = Vec2::Zero();  // pseudo velocity (split impulses): moves positions only
  double pw = 0.0;
  double inv_inertia = 0.0;
};

struct ContactPointRow {
  Vec2 ra = Vec2::Zero();  // contact point relative to body A's centre of mass
  Vec2 rb = Vec2::Zero();
  double normal_mass = 0.0;   // 1 / (J M^-1 J^T) for the normal row
  double tangent_mass = 0.0;  // the same for the friction row
  double target = 0.0;         // required normal separation speed (speculative, Baumgarte)
  double pseudo_target = 0.0;  // split impulses: position-correction speed
  double normal_impulse = 0.0;   // accumulated
  double tangent_impulse = 0.0;  // accumulated
  double pseudo_impulse = 0.0;   // accumulated, on pseudo velocities
  double max_normal_impulse = 0.0;
  double approach_speed = 0.0;  // normal relative velocity before solving (restitution)
};

struct ContactRow {
  int contact = -1;
  int ia = 0, ib = 0;  // solver body slots (0: the shared static body)
  Vec2 normal = Vec2::Zero();
  double friction = 0.0;
  double restitution = 0.0;
  int count = 0;
  bool block = false;   // solve both normal rows together
  Mat22 k;              // 2x2 effective-mass matrix of the normal rows
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
