// The common form every constraint is written in (MISSION.md; Catto, "Modeling and Solving
// Constraints", GDC 2009):
//   velocity constraint  J v + b = 0 (or >= 0),  J = [J_va, J_wa, J_vb, J_wb]
//   effective mass       m_c = 1 / (J M^-1 J^T),  M = diag(m_a, m_a, I_a, m_b, m_b, I_b)
//   corrective impulse   lambda = -m_c s_m (J v + b) - s_i * accumulated   (soft rows; rigid:
//                        s_m = 1, s_i = 0)
//   clamping             the accumulated impulse, never the corrective one, in [lower, upper]
//   applied impulse      P = J^T lambda,  v += M^-1 P
// Joints are built from these rows. Contacts use the same rows (an axis row along the normal
// bounded to [0, inf), one along the tangent bounded by +-mu times the normal impulse),
// written out on plain doubles in contact_solver.cpp because they are the hot loop.
#pragma once

#include <algorithm>
#include <limits>

#include "contact_solver.h"
#include "fulcrum/math.h"

namespace fulcrum {

struct RowJacobian {
  Vec2 linear_a = Vec2::Zero();
  double angular_a = 0.0;
  Vec2 linear_b = Vec2::Zero();
  double angular_b = 0.0;
};

struct ConstraintRow {
  RowJacobian j;
  double effective_mass = 0.0;                              // m_c
  double bias = 0.0;                                        // b, m/s (or rad/s)
  double lower = -std::numeric_limits<double>::infinity();  // bounds on the accumulated
  double upper = std::numeric_limits<double>::infinity();   // impulse, N s (or N m s)
  Softness softness;
  double impulse = 0.0;  // accumulated
};

// A point row along unit axis n between anchors ra, rb (relative to the centres of mass):
// C = n . (pb - pa), J = [-n, -(ra x n), n, rb x n]. Contact normals, friction, prismatic and
// distance rows.
inline RowJacobian axis_jacobian(const Vec2& n, const Vec2& ra, const Vec2& rb) {
  return RowJacobian{-n, -cross(ra, n), n, cross(rb, n)};
}

// An angle row: C = angle_b - angle_a - target, J = [0, -1, 0, 1]. Welds, limits, motors.
inline RowJacobian angle_jacobian() {
  return RowJacobian{Vec2::Zero(), -1.0, Vec2::Zero(), 1.0};
}

// m_c = 1 / (J M^-1 J^T), or 0 when the row cannot move anything.
inline double effective_mass(const RowJacobian& j, const ScalarBody& a, const ScalarBody& b) {
  double k = a.inv_mass * dot(j.linear_a, j.linear_a) + a.inv_inertia * j.angular_a * j.angular_a +
             b.inv_mass * dot(j.linear_b, j.linear_b) + b.inv_inertia * j.angular_b * j.angular_b;
  return k > 0.0 ? 1.0 / k : 0.0;
}

// J v.
inline double row_velocity(const RowJacobian& j, const ScalarBody& a, const ScalarBody& b) {
  return j.linear_a.x() * a.vx + j.linear_a.y() * a.vy + j.angular_a * a.w + j.linear_b.x() * b.vx +
         j.linear_b.y() * b.vy + j.angular_b * b.w;
}

// v += M^-1 J^T lambda.
inline void apply_row_impulse(const RowJacobian& j, double lambda, ScalarBody& a, ScalarBody& b) {
  a.vx += a.inv_mass * (lambda * j.linear_a.x());
  a.vy += a.inv_mass * (lambda * j.linear_a.y());
  a.w += a.inv_inertia * (lambda * j.angular_a);
  b.vx += b.inv_mass * (lambda * j.linear_b.x());
  b.vy += b.inv_mass * (lambda * j.linear_b.y());
  b.w += b.inv_inertia * (lambda * j.angular_b);
}

// One sequential-impulse update of one row; returns the impulse applied this time.
inline double solve_row(ConstraintRow& row, ScalarBody& a, ScalarBody& b) {
  double lambda =
      -row.effective_mass * row.softness.mass_scale * (row_velocity(row.j, a, b) + row.bias) -
      row.softness.impulse_scale * row.impulse;
  double accumulated = std::clamp(row.impulse + lambda, row.lower, row.upper);
  lambda = accumulated - row.impulse;
  row.impulse = accumulated;
  apply_row_impulse(row.j, lambda, a, b);
  return lambda;
}

}  // namespace fulcrum
