// The common row form: facts that every joint and contact row relies on.
#include "constraint_row.h"

#include <gtest/gtest.h>

#include <cmath>

namespace fulcrum {
namespace {

ScalarBody body(double m, double i, double vx, double vy, double w) {
  ScalarBody b;
  b.inv_mass = m > 0.0 ? 1.0 / m : 0.0;
  b.inv_inertia = i > 0.0 ? 1.0 / i : 0.0;
  b.vx = vx;
  b.vy = vy;
  b.w = w;
  return b;
}

// An unbounded rigid row with b = 0 removes J v in one update: J M^-1 J^T m_c = 1, so the
// residual is rounding only (1e-12 on velocities of order 1).
TEST(ConstraintRow, UnboundedRowSatisfiesItselfInOneUpdate) {
  ScalarBody a = body(2.0, 0.5, 1.0, -2.0, 0.3);
  ScalarBody b = body(1.0, 0.2, -0.5, 0.7, -1.1);
  ConstraintRow row;
  row.j = axis_jacobian(Vec2(0.6, 0.8), Vec2(0.3, -0.2), Vec2(-0.4, 0.1));
  row.effective_mass = effective_mass(row.j, a, b);
  solve_row(row, a, b);
  EXPECT_NEAR(row_velocity(row.j, a, b), 0.0, 1e-12);
}

// The contact normal's effective mass matches its closed form
// 1 / (1/ma + 1/mb + (ra x n)^2 / Ia + (rb x n)^2 / Ib).
TEST(ConstraintRow, AxisRowEffectiveMassMatchesClosedForm) {
  ScalarBody a = body(3.0, 0.7, 0, 0, 0), b = body(1.5, 0.4, 0, 0, 0);
  Vec2 n(0.0, 1.0), ra(0.5, 0.5), rb(-0.5, -0.5);
  double rna = cross(ra, n), rnb = cross(rb, n);
  double expected = 1.0 / (1.0 / 3.0 + 1.0 / 1.5 + rna * rna / 0.7 + rnb * rnb / 0.4);
  EXPECT_NEAR(effective_mass(axis_jacobian(n, ra, rb), a, b), expected, 1e-15);
}

// The accumulated impulse is clamped, never the corrective one: a contact row (lower 0)
// pushes apart but never pulls, and a row already at its bound can come back off it.
TEST(ConstraintRow, AccumulatedImpulseIsClamped) {
  ScalarBody ground = body(0.0, 0.0, 0, 0, 0);
  ScalarBody box = body(1.0, 0.0, 0.0, 2.0, 0.0);  // separating at 2 m/s
  ConstraintRow row;
  row.j = axis_jacobian(Vec2(0.0, 1.0), Vec2::Zero(), Vec2::Zero());
  row.effective_mass = effective_mass(row.j, ground, box);
  row.lower = 0.0;
  row.impulse = 0.5;  // warm start: half a newton-second already applied
  double applied = solve_row(row, ground, box);
  EXPECT_EQ(row.impulse, 0.0);  // cannot pull: the accumulated impulse stops at 0
  EXPECT_EQ(applied, -0.5);     // by taking back exactly what it had applied
  EXPECT_NEAR(box.vy, 1.5, 1e-15);
}

// Momentum: a row between two free bodies applies equal and opposite linear impulses.
TEST(ConstraintRow, RowConservesLinearMomentum) {
  ScalarBody a = body(2.0, 1.0, 1.0, 0.0, 0.0), b = body(3.0, 1.0, -1.0, 0.5, 0.0);
  double px = 2.0 * a.vx + 3.0 * b.vx, py = 2.0 * a.vy + 3.0 * b.vy;
  ConstraintRow row;
  row.j = axis_jacobian(Vec2(1.0, 0.0), Vec2(0.0, 0.2), Vec2(0.0, -0.1));
  row.effective_mass = effective_mass(row.j, a, b);
  solve_row(row, a, b);
  EXPECT_NEAR(2.0 * a.vx + 3.0 * b.vx, px, 1e-14);
  EXPECT_NEAR(2.0 * a.vy + 3.0 * b.vy, py, 1e-14);
}

// An angle row stops relative rotation: after one update wb - wa = 0.
TEST(ConstraintRow, AngleRowStopsRelativeSpin) {
  ScalarBody a = body(1.0, 0.5, 0, 0, 2.0), b = body(1.0, 0.25, 0, 0, -1.0);
  ConstraintRow row;
  row.j = angle_jacobian();
  row.effective_mass = effective_mass(row.j, a, b);
  solve_row(row, a, b);
  EXPECT_NEAR(b.w - a.w, 0.0, 1e-15);
  // Angular momentum 0.5 * 2 + 0.25 * (-1) = 0.75 is kept.
  EXPECT_NEAR(0.5 * a.w + 0.25 * b.w, 0.75, 1e-15);
}

}  // namespace
}  // namespace fulcrum
