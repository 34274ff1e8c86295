// Weld joint: the point constraint of the revolute joint plus an angle row.
//   Point:  C = (cb + rb) - (ca + ra),  K as in revolute_joint.cpp
//   Angle:  C = angle_b - angle_a - reference,  J = [0, -1, 0, 1],  m = 1 / (ia + ib)
// Each part is rigid (the world's joint feedback) or a spring of its own frequency. The
// angle row is solved first, the point row last. The point's feedback closes no faster than
// max_correction_speed (joint_solver.h); its own spring and the angle row are not capped.
#include "joint_solver.h"
#include "world_impl.h"

namespace fulcrum {

void warm_start_weld_joint(const Joint& j, const JointRow& r, ScalarBody& a, ScalarBody& b) {
  JointFrame f = joint_frame(r, a, b);
  apply_joint_impulse(f, j.linear_impulse.x(), j.linear_impulse.y(), a, b);
  a.w -= a.inv_inertia * j.axial_impulse;
  b.w += b.inv_inertia * j.axial_impulse;
}

void solve_weld_joint(Joint& j, const JointRow& r, const JointStep& st, ScalarBody& a,
                      ScalarBody& b) {
  // Angle: a spring when the weld has angular_hertz, else rigid with the world's feedback.
  if (a.inv_inertia + b.inv_inertia > 0.0) {
    double c = r.angle + (b.da - a.da);
    double bias, ms, is;
    if (j.angular_hertz > 0.0) {
      bias = r.angular_spring.bias_rate * c;
      ms = r.angular_spring.mass_scale;
      is = r.angular_spring.impulse_scale;
    } else {
      joint_bias(st, r.soft, c, &bias, &ms, &is);
    }
    double lambda = -ms * r.axial_mass * ((b.w - a.w) + bias) - is * j.axial_impulse;
    j.axial_impulse += lambda;
    a.w -= a.inv_inertia * lambda;
    b.w += b.inv_inertia * lambda;
  }
  // Point: two rows through K.
  JointFrame f = joint_frame(r, a, b);
  double cdx = (b.vx - b.w * f.rby) - (a.vx - a.w * f.ray);
  double cdy = (b.vy + b.w * f.rbx) - (a.vy + a.w * f.rax);
  double rate = 0.0, ms = 1.0, is = 0.0;
  if (j.hertz > 0.0) {
    rate = r.spring.bias_rate;
    ms = r.spring.mass_scale;
    is = r.spring.impulse_scale;
  } else if (st.use_bias) {
    rate = st.rigid ? st.baumgarte * st.inv_h : r.soft.bias_rate;
    if (!st.rigid) {
      ms = r.soft.mass_scale;
      is = r.soft.impulse_scale;
    }
  }
  double m = a.inv_mass + b.inv_mass;
  double k11 = m + a.inv_inertia * f.ray * f.ray + b.inv_inertia * f.rby * f.rby;
  double k12 = -a.inv_inertia * f.rax * f.ray - b.inv_inertia * f.rbx * f.rby;
  double k22 = m + a.inv_inertia * f.rax * f.rax + b.inv_inertia * f.rbx * f.rbx;
  double det = k11 * k22 - k12 * k12;
  if (det == 0.0) return;
  double inv_det = 1.0 / det;
  double rx = cdx + rate * f.dx, ry = cdy + rate * f.dy;
  double px = -ms * inv_det * (k22 * rx - k12 * ry) - is * j.linear_impulse.x();
  double py = -ms * inv_det * (k11 * ry - k12 * rx) - is * j.linear_impulse.y();
  if (j.hertz == 0.0) {  // the world's feedback, capped; a weld's own spring is a force, not
                         // drift correction
    Vec2 capped = capped_point_correction(st, k11, k12, k22, inv_det, rate * f.dx, rate * f.dy, ms,
                                          is, j.linear_impulse);
    px += capped.x();
    py += capped.y();
  }
  j.linear_impulse += Vec2(px, py);
  apply_joint_impulse(f, px, py, a, b);
}

}  // namespace fulcrum
