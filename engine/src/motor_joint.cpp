// Motor joint: a position motor that drives body B's origin and angle toward an offset pose
// relative to body A, which may change every tick (Box2D's motor joint).
//   Linear:   C = xb - (xa + Ra offset) = (cb + rb) - (ca + ra),  ra = Ra offset - Ra lc_a,
//             rb = -Rb lc_b (B's origin);  K as in revolute_joint.cpp
//   Angular:  C = angle_b - angle_a - angular_offset,  J = [0, -1, 0, 1],  m = 1 / (ia + ib)
// Each row is driven toward zero error at the speed (correction_factor / h) C (the motor's
// target velocity, kept in every pass: this is the drive, not drift correction), with the
// accumulated impulse capped at max_torque h (angular) and max_force h (linear, by length).
// Solved in order angular, linear.
#include <algorithm>
#include <cmath>

#include "joint_solver.h"
#include "validation.h"
#include "world_impl.h"

namespace fulcrum {

Status validate_motor_joint_def(const MotorJointDef& d) {
  FULCRUM_RETURN_IF_ERROR(check_finite("joint.linear_offset", d.linear_offset));
  FULCRUM_RETURN_IF_ERROR(check_finite("joint.angular_offset", d.angular_offset));
  FULCRUM_RETURN_IF_ERROR(check_cap("joint.max_force", d.max_force));
  FULCRUM_RETURN_IF_ERROR(check_cap("joint.max_torque", d.max_torque));
  FULCRUM_RETURN_IF_ERROR(check_in_range("joint.correction_factor", d.correction_factor, 0.0, 1.0));
  return {};
}

Result<JointId> World::create_motor_joint(const MotorJointDef& def) {
  FULCRUM_RETURN_IF_ERROR(validate_motor_joint_def(def));
  Result<int> ji =
      impl_->add_joint(JointType::kMotor, def.body_a, def.body_b, def.collide_connected);
  if (!ji.ok()) return ji.status();
  Joint& j = impl_->joints[*ji];
  j.local_a = def.linear_offset;
  j.local_b = Vec2::Zero();
  j.reference_angle = def.angular_offset;
  j.max_force = def.max_force;
  j.max_motor_torque = def.max_torque;
  j.correction_factor = def.correction_factor;
  return impl_->joint_id(*ji);
}

Status World::set_motor_joint_targets(JointId id, const Vec2& linear_offset,
                                      double angular_offset) {
  int ji = impl_->joint_index(id);
  if (ji == kNullIndex) return not_found("joint: unknown or destroyed joint handle");
  Joint& j = impl_->joints[ji];
  if (j.type != JointType::kMotor) return invalid_argument("joint: not a motor joint");
  FULCRUM_RETURN_IF_ERROR(check_finite("linear_offset", linear_offset));
  FULCRUM_RETURN_IF_ERROR(check_finite("angular_offset", angular_offset));
  j.local_a = linear_offset;
  j.reference_angle = angular_offset;
  impl_->wake_island(j.body_a);
  impl_->wake_island(j.body_b);
  return {};
}

void warm_start_motor_joint(const Joint& j, const JointRow& r, ScalarBody& a, ScalarBody& b) {
  JointFrame f = joint_frame(r, a, b);
  apply_joint_impulse(f, j.linear_impulse.x(), j.linear_impulse.y(), a, b);
  a.w -= a.inv_inertia * j.axial_impulse;
  b.w += b.inv_inertia * j.axial_impulse;
}

void solve_motor_joint(Joint& j, const JointRow& r, const JointStep& st, ScalarBody& a,
                       ScalarBody& b) {
  const double rate = j.correction_factor * st.inv_h;
  if (a.inv_inertia + b.inv_inertia > 0.0) {
    double c = r.angle + (b.da - a.da);
    double lambda = -r.axial_mass * ((b.w - a.w) + rate * c);
    double limit = j.max_motor_torque * st.h;
    double acc = std::clamp(j.axial_impulse + lambda, -limit, limit);
    lambda = acc - j.axial_impulse;
    j.axial_impulse = acc;
    a.w -= a.inv_inertia * lambda;
    b.w += b.inv_inertia * lambda;
  }
  JointFrame f = joint_frame(r, a, b);
  double cdx = (b.vx - b.w * f.rby) - (a.vx - a.w * f.ray);
  double cdy = (b.vy + b.w * f.rbx) - (a.vy + a.w * f.rax);
  double m = a.inv_mass + b.inv_mass;
  double k11 = m + a.inv_inertia * f.ray * f.ray + b.inv_inertia * f.rby * f.rby;
  double k12 = -a.inv_inertia * f.rax * f.ray - b.inv_inertia * f.rbx * f.rby;
  double k22 = m + a.inv_inertia * f.rax * f.rax + b.inv_inertia * f.rbx * f.rbx;
  double det = k11 * k22 - k12 * k12;
  if (det == 0.0) return;
  double inv_det = 1.0 / det;
  double rx = cdx + rate * f.dx, ry = cdy + rate * f.dy;
  Vec2 old = j.linear_impulse;
  Vec2 acc = old - inv_det * Vec2(k22 * rx - k12 * ry, k11 * ry - k12 * rx);
  double limit = j.max_force * st.h;
  double size = length(acc);
  if (size > limit) acc *= limit / size;
  j.linear_impulse = acc;
  apply_joint_impulse(f, acc.x() - old.x(), acc.y() - old.y(), a, b);
}

}  // namespace fulcrum
