// Revolute joint: the talk's point constraint, plus an angle limit, a velocity motor and an
// angular spring on the relative angle.
//   Point:  C = (cb + rb) - (ca + ra)  (two rows),  dC/dt = vb + wb x rb - va - wa x ra
//           K = J M^-1 J^T = [ma + mb + ia ra.y^2 + ib rb.y^2, -ia ra.x ra.y - ib rb.x rb.y;
//                             same,  ma + mb + ia ra.x^2 + ib rb.x^2]
//   Angle:  theta = angle_b - angle_a - reference,  J = [0, -1, 0, 1],  m = 1 / (ia + ib)
//   Limits: theta - lower >= 0 and upper - theta >= 0 (inequalities, speculative until hit)
//   Motor:  dtheta/dt - speed = 0, |accumulated| <= max_torque h
//   Spring: soft row toward target_angle.
// Solved in order spring, motor, limits, point: the point row, solved last, matters most. The
// point's feedback closes no faster than max_correction_speed (joint_solver.h); the angle
// rows' is not capped (the cap is a speed in m/s).
//
// Every revolute joint is solved in lanes, colour by colour (joint_lanes.h; the passes are
// joint_kernel.h's). Here: the angle rows' mass, when the row is prepared.
#include "joint_solver.h"

namespace fulcrum {

void prepare_revolute_joint(const Joint& j, JointRow& r, const ScalarBody& a, const ScalarBody& b) {
  double k = a.inv_inertia + b.inv_inertia;
  r.axial_mass = k > 0.0 ? 1.0 / k : 0.0;
  (void)j;
}

}  // namespace fulcrum
