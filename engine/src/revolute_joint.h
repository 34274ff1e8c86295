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
// The passes' functions are inline, so that the solver's loop over the joints keeps the two
// bodies' velocities in registers through a joint's five rows instead of passing them through
// memory from call to call.
#pragma once

#include <algorithm>
#include <cmath>

#include "joint_solver.h"

namespace fulcrum {

namespace revolute_detail {

inline void apply_angular(double lambda, ScalarBody& a, ScalarBody& b) {
  a.w -= a.inv_inertia * lambda;
  b.w += b.inv_inertia * lambda;
}

}  // namespace revolute_detail

// A revolute joint's point rows, solved together through K, with its accumulated point impulse
// in `impulse` (x, y).
__attribute__((always_inline)) inline void solve_revolute_point(const JointRow& r,
                                                                const JointStep& st,
                                                                double* impulse, ScalarBody& a,
                                                                ScalarBody& b) {
  JointFrame f = joint_frame(r, a, b);
  double cdx = (b.vx - b.w * f.rby) - (a.vx - a.w * f.ray);
  double cdy = (b.vy + b.w * f.rbx) - (a.vy + a.w * f.rax);
  double bias_x = 0.0, bias_y = 0.0, ms = 1.0, is = 0.0;
  if (st.use_bias) {
    double rate = st.baumgarte * st.inv_h;
    if (!st.rigid) {
      rate = r.soft.bias_rate;
      ms = r.soft.mass_scale;
      is = r.soft.impulse_scale;
    }
    bias_x = rate * f.dx;
    bias_y = rate * f.dy;
  }
  double m = a.inv_mass + b.inv_mass;
  double k11 = m + a.inv_inertia * f.ray * f.ray + b.inv_inertia * f.rby * f.rby;
  double k12 = -a.inv_inertia * f.rax * f.ray - b.inv_inertia * f.rbx * f.rby;
  double k22 = m + a.inv_inertia * f.rax * f.rax + b.inv_inertia * f.rbx * f.rbx;
  double det = k11 * k22 - k12 * k12;
  if (det == 0.0) return;  // two immovable bodies
  double inv_det = 1.0 / det;
  double rx = cdx + bias_x, ry = cdy + bias_y;
  double sx = inv_det * (k22 * rx - k12 * ry);
  double sy = inv_det * (k11 * ry - k12 * rx);
  double px = -ms * sx - is * impulse[0];
  double py = -ms * sy - is * impulse[1];
  Vec2 capped = capped_point_correction(st, k11, k12, k22, inv_det, bias_x, bias_y, ms, is,
                                        Vec2(impulse[0], impulse[1]));
  px += capped.x();
  py += capped.y();
  impulse[0] += px;
  impulse[1] += py;
  apply_joint_impulse(f, px, py, a, b);
}

__attribute__((always_inline)) inline void warm_start_revolute_joint(const JointRow& r,
                                                                     ScalarBody& a, ScalarBody& b) {
  const RevoluteRow& v = r.revolute;
  JointFrame f = joint_frame(r, a, b);
  double axial = v.spring_impulse + v.motor_impulse + v.lower_impulse - v.upper_impulse;
  apply_joint_impulse(f, r.ix, r.iy, a, b);
  revolute_detail::apply_angular(axial, a, b);
}

__attribute__((always_inline)) inline void solve_revolute_joint(JointRow& r, const JointStep& st,
                                                                ScalarBody& a, ScalarBody& b) {
  RevoluteRow& v = r.revolute;
  const bool turns = a.inv_inertia + b.inv_inertia > 0.0;
  const double theta = r.angle + (b.da - a.da);

  if (v.spring && turns) {
    double c = theta - v.target_angle;
    double lambda = -r.spring.mass_scale * r.axial_mass * ((b.w - a.w) + r.spring.bias_rate * c) -
                    r.spring.impulse_scale * v.spring_impulse;
    v.spring_impulse += lambda;
    revolute_detail::apply_angular(lambda, a, b);
  }
  if (v.motor && turns) {
    double lambda = -r.axial_mass * ((b.w - a.w) - v.motor_speed);
    double limit = v.max_motor_torque * st.h;
    double acc = std::clamp(v.motor_impulse + lambda, -limit, limit);
    lambda = acc - v.motor_impulse;
    v.motor_impulse = acc;
    revolute_detail::apply_angular(lambda, a, b);
  }
  if (v.limit && turns) {
    double bias, ms, is;
    // Lower: theta - lower >= 0.
    double c = theta - v.lower_angle;
    limit_bias(st, r.soft, c, &bias, &ms, &is);
    double lambda = -ms * r.axial_mass * ((b.w - a.w) + bias) - is * v.lower_impulse;
    double acc = std::max(v.lower_impulse + lambda, 0.0);
    lambda = acc - v.lower_impulse;
    v.lower_impulse = acc;
    revolute_detail::apply_angular(lambda, a, b);
    // Upper: upper - theta >= 0.
    c = v.upper_angle - theta;
    limit_bias(st, r.soft, c, &bias, &ms, &is);
    lambda = -ms * r.axial_mass * ((a.w - b.w) + bias) - is * v.upper_impulse;
    acc = std::max(v.upper_impulse + lambda, 0.0);
    lambda = acc - v.upper_impulse;
    v.upper_impulse = acc;
    revolute_detail::apply_angular(-lambda, a, b);
  }

  // The point: two rows solved together through K.
  double impulse[2] = {r.ix, r.iy};
  solve_revolute_point(r, st, impulse, a, b);
  r.ix = impulse[0];
  r.iy = impulse[1];
}

}  // namespace fulcrum
