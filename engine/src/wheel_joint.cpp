// Wheel joint: body B's anchor stays on a line through body A's anchor along an axis u fixed
// in A (the suspension travel), while B turns freely (Box2D's wheel joint).
//   d = (cb + rb) - (ca + ra),  u turns with A,  p = perp(u)
//   Line:    C = p . d,  J = [-p, -(d + ra) x p, p, rb x p]
//            m = 1 / (ma + mb + ia s1^2 + ib s2^2),  s1 = (d + ra) x p, s2 = rb x p
//   Spring:  soft row C = u . d (rest at translation 0) of the suspension's frequency,
//            J = [-u, -(d + ra) x u, u, rb x u],  m = 1 / (ma + mb + ia a1^2 + ib a2^2)
//   Limits:  t - lower >= 0 and upper - t >= 0 on t = u . d (as the prismatic joint's)
//   Motor:   wb - wa - speed = 0,  J = [0, -1, 0, 1],  m = 1 / (ia + ib),
//            |accumulated| <= max_motor_torque h
// Solved in order motor, spring, limits, line: the line row, solved last, matters most. The
// line row's and the limits' feedback closes no faster than max_correction_speed
// (joint_solver.h); the spring and the motor are not capped.
#include <algorithm>
#include <cmath>

#include "joint_solver.h"
#include "validation.h"
#include "world_impl.h"

namespace fulcrum {

Status validate_wheel_joint_def(const WheelJointDef& d) {
  FULCRUM_RETURN_IF_ERROR(check_finite("joint.local_anchor_a", d.local_anchor_a));
  FULCRUM_RETURN_IF_ERROR(check_finite("joint.local_anchor_b", d.local_anchor_b));
  FULCRUM_RETURN_IF_ERROR(check_finite("joint.local_axis_a", d.local_axis_a));
  if (length(d.local_axis_a) < 1e-9) {
    return invalid_argument("joint.local_axis_a: must not be zero");
  }
  FULCRUM_RETURN_IF_ERROR(check_non_negative("joint.hertz", d.hertz));
  FULCRUM_RETURN_IF_ERROR(check_non_negative("joint.damping_ratio", d.damping_ratio));
  FULCRUM_RETURN_IF_ERROR(check_finite("joint.lower_translation", d.lower_translation));
  FULCRUM_RETURN_IF_ERROR(check_finite("joint.upper_translation", d.upper_translation));
  if (d.lower_translation > d.upper_translation) {
    return invalid_argument("joint.lower_translation: must be <= upper_translation (got " +
                            format_number(d.lower_translation) + " > " +
                            format_number(d.upper_translation) + ")");
  }
  FULCRUM_RETURN_IF_ERROR(check_finite("joint.motor_speed", d.motor_speed));
  FULCRUM_RETURN_IF_ERROR(check_cap("joint.max_motor_torque", d.max_motor_torque));
  return {};
}

Result<JointId> World::create_wheel_joint(const WheelJointDef& def) {
  FULCRUM_RETURN_IF_ERROR(validate_wheel_joint_def(def));
  Result<int> ji =
      impl_->add_joint(JointType::kWheel, def.body_a, def.body_b, def.collide_connected);
  if (!ji.ok()) return ji.status();
  Joint& j = impl_->joints[*ji];
  j.local_a = def.local_anchor_a;
  j.local_b = def.local_anchor_b;
  j.local_axis = normalize_or_zero(def.local_axis_a);
  j.enable_spring = def.enable_spring;
  j.hertz = def.enable_spring ? def.hertz : 0.0;
  j.damping_ratio = def.damping_ratio;
  j.enable_limit = def.enable_limit;
  j.lower_angle = def.lower_translation;  // translations, in the limit fields
  j.upper_angle = def.upper_translation;
  j.enable_motor = def.enable_motor;
  j.motor_speed = def.motor_speed;
  j.max_motor_torque = def.max_motor_torque;
  return impl_->joint_id(*ji);
}

void warm_start_wheel_joint(const Joint& j, const JointRow& r, ScalarBody& a, ScalarBody& b) {
  LineFrame fr = line_frame(r, a, b);
  double axial = j.spring_impulse + j.lower_impulse - j.upper_impulse;
  double perp = j.linear_impulse.x();
  double px = axial * fr.ux - perp * fr.uy, py = axial * fr.uy + perp * fr.ux;
  double la = axial * fr.a1 + perp * fr.s1 + j.motor_impulse;
  double lb = axial * fr.a2 + perp * fr.s2 + j.motor_impulse;
  a.vx -= a.inv_mass * px;
  a.vy -= a.inv_mass * py;
  a.w -= a.inv_inertia * la;
  b.vx += b.inv_mass * px;
  b.vy += b.inv_mass * py;
  b.w += b.inv_inertia * lb;
}

void solve_wheel_joint(Joint& j, const JointRow& r, const JointStep& st, ScalarBody& a,
                       ScalarBody& b) {
  if (j.enable_motor && a.inv_inertia + b.inv_inertia > 0.0) {
    double lambda = -r.axial_mass * ((b.w - a.w) - j.motor_speed);
    double limit = j.max_motor_torque * st.h;
    double acc = std::clamp(j.motor_impulse + lambda, -limit, limit);
    lambda = acc - j.motor_impulse;
    j.motor_impulse = acc;
    a.w -= a.inv_inertia * lambda;
    b.w += b.inv_inertia * lambda;
  }
  LineFrame fr = line_frame(r, a, b);
  if (j.hertz > 0.0 || j.enable_limit) {
    const double m = line_axial_mass(fr, a, b);
    if (j.hertz > 0.0) {
      double c = fr.ux * fr.f.dx + fr.uy * fr.f.dy;
      double lambda =
          -r.spring.mass_scale * m * (line_axial_speed(fr, a, b) + r.spring.bias_rate * c) -
          r.spring.impulse_scale * j.spring_impulse;
      j.spring_impulse += lambda;
      apply_line_axial(fr, lambda, a, b);
    }
    if (j.enable_limit) solve_line_limits(j, fr, m, r, st, a, b);
  }
  // The line row.
  const double px = -fr.uy, py = fr.ux;
  double k =
      a.inv_mass + b.inv_mass + a.inv_inertia * fr.s1 * fr.s1 + b.inv_inertia * fr.s2 * fr.s2;
  if (k == 0.0) return;
  double cdot = px * (b.vx - a.vx) + py * (b.vy - a.vy) + fr.s2 * b.w - fr.s1 * a.w;
  double bias, ms, is;
  joint_bias(st, r.soft, px * fr.f.dx + py * fr.f.dy, &bias, &ms, &is);
  double lambda = -ms * (cdot + bias) / k - is * j.linear_impulse.x();
  lambda = capped_row_impulse(st, lambda, 1.0 / k, cdot, bias, ms, is, j.linear_impulse.x(), false);
  j.linear_impulse.x() += lambda;
  double qx = lambda * px, qy = lambda * py;
  a.vx -= a.inv_mass * qx;
  a.vy -= a.inv_mass * qy;
  a.w -= a.inv_inertia * (lambda * fr.s1);
  b.vx += b.inv_mass * qx;
  b.vy += b.inv_mass * qy;
  b.w += b.inv_inertia * (lambda * fr.s2);
}

}  // namespace fulcrum
