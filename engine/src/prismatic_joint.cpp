// Prismatic joint: body B slides along an axis u fixed in body A and keeps its angle.
//   d = (cb + rb) - (ca + ra),  u turns with A,  p = perp(u)
//   Line:   C1 = p . d,  J1 = [-p, -(d + ra) x p, p, rb x p]
//   Angle:  C2 = angle_b - angle_a - reference,  J2 = [0, -1, 0, 1]   (solved with C1 as 2x2)
//   Axis:   translation t = u . d,  J = [-u, -(d + ra) x u, u, rb x u]: limits t - lower >= 0,
//           upper - t >= 0; motor dt/dt - speed = 0 with |accumulated| <= max_force h;
//           spring: a soft row C = t - target_translation of the spring's frequency,
//           m = 1 / (ma + mb + ia a1^2 + ib a2^2) (LineFrame in joint_solver.h).
// Solved in order spring, motor, limits, line and angle. The limits' feedback closes no faster
// than max_correction_speed (joint_solver.h). The line row's is not capped: it is solved in one
// block with the angle row, whose coupling (k12) mixes the angle row's accumulated impulse into
// the line row's closing speed, and capping that one component of a nearly singular block
// (k12^2 close to k11 k22 when B's anchor is far from A's centre) made the impulses blow up.
#include <algorithm>
#include <cmath>

#include "joint_solver.h"
#include "world_impl.h"

namespace fulcrum {

void solve_line_limits(Joint& j, const LineFrame& fr, double m, const JointRow& r,
                       const JointStep& st, ScalarBody& a, ScalarBody& b) {
  const double t = fr.ux * fr.f.dx + fr.uy * fr.f.dy;
  double bias, ms, is;
  double c = t - j.lower_angle;  // lower translation
  limit_bias(st, r.soft, c, &bias, &ms, &is);
  double cdot = line_axial_speed(fr, a, b);
  double lambda = -ms * m * (cdot + bias) - is * j.lower_impulse;
  lambda = capped_row_impulse(st, lambda, m, cdot, bias, ms, is, j.lower_impulse, true);
  double acc = std::max(j.lower_impulse + lambda, 0.0);
  lambda = acc - j.lower_impulse;
  j.lower_impulse = acc;
  apply_line_axial(fr, lambda, a, b);
  c = j.upper_angle - t;  // upper translation
  limit_bias(st, r.soft, c, &bias, &ms, &is);
  cdot = -line_axial_speed(fr, a, b);
  lambda = -ms * m * (cdot + bias) - is * j.upper_impulse;
  lambda = capped_row_impulse(st, lambda, m, cdot, bias, ms, is, j.upper_impulse, true);
  acc = std::max(j.upper_impulse + lambda, 0.0);
  lambda = acc - j.upper_impulse;
  j.upper_impulse = acc;
  apply_line_axial(fr, -lambda, a, b);
}

void warm_start_prismatic_joint(const Joint& j, const JointRow& r, ScalarBody& a, ScalarBody& b) {
  LineFrame fr = line_frame(r, a, b);
  double axial = j.motor_impulse + j.lower_impulse - j.upper_impulse;
  if (j.enable_spring) axial += j.spring_impulse;
  double perp = j.linear_impulse.x(), angle = j.linear_impulse.y();
  double px = axial * fr.ux - perp * fr.uy, py = axial * fr.uy + perp * fr.ux;
  double la = axial * fr.a1 + perp * fr.s1 + angle;
  double lb = axial * fr.a2 + perp * fr.s2 + angle;
  a.vx -= a.inv_mass * px;
  a.vy -= a.inv_mass * py;
  a.w -= a.inv_inertia * la;
  b.vx += b.inv_mass * px;
  b.vy += b.inv_mass * py;
  b.w += b.inv_inertia * lb;
}

void solve_prismatic_joint(Joint& j, const JointRow& r, const JointStep& st, ScalarBody& a,
                           ScalarBody& b) {
  LineFrame fr = line_frame(r, a, b);
  const double m = line_axial_mass(fr, a, b);
  if (j.enable_spring && j.hertz > 0.0) {
    double c = fr.ux * fr.f.dx + fr.uy * fr.f.dy - j.target_translation;
    double lambda =
        -r.spring.mass_scale * m * (line_axial_speed(fr, a, b) + r.spring.bias_rate * c) -
        r.spring.impulse_scale * j.spring_impulse;
    j.spring_impulse += lambda;
    apply_line_axial(fr, lambda, a, b);
  }
  if (j.enable_motor) {
    double lambda = m * (j.motor_speed - line_axial_speed(fr, a, b));
    double limit = j.max_motor_force * st.h;
    double acc = std::clamp(j.motor_impulse + lambda, -limit, limit);
    lambda = acc - j.motor_impulse;
    j.motor_impulse = acc;
    apply_line_axial(fr, lambda, a, b);
  }
  if (j.enable_limit) solve_line_limits(j, fr, m, r, st, a, b);
  // Line and angle together.
  const double px = -fr.uy, py = fr.ux;
  double cd1 = px * (b.vx - a.vx) + py * (b.vy - a.vy) + fr.s2 * b.w - fr.s1 * a.w;
  double cd2 = b.w - a.w;
  double bias1 = 0.0, bias2 = 0.0, ms = 1.0, is = 0.0;
  if (st.use_bias) {
    double c1 = px * fr.f.dx + py * fr.f.dy;
    double c2 = r.angle + (b.da - a.da);
    double rate = st.baumgarte * st.inv_h;
    if (!st.rigid) {
      rate = r.soft.bias_rate;
      ms = r.soft.mass_scale;
      is = r.soft.impulse_scale;
    }
    bias1 = rate * c1;
    bias2 = rate * c2;
  }
  double k11 =
      a.inv_mass + b.inv_mass + a.inv_inertia * fr.s1 * fr.s1 + b.inv_inertia * fr.s2 * fr.s2;
  double k12 = a.inv_inertia * fr.s1 + b.inv_inertia * fr.s2;
  double k22 = a.inv_inertia + b.inv_inertia;
  if (k22 == 0.0) k22 = 1.0;  // neither body turns: the angle row is inert
  // k11 k22 - k12^2 written without the cancellation: (ma + mb) k22 + ia ib (s1 - s2)^2. The
  // two products it subtracts grow with the squared lever arms, so once the bodies drift apart
  // (or one turns easily) their difference lost every digit, came out zero or negative, and
  // the impulse overflowed.
  const double ds = fr.s1 - fr.s2;
  double det = (a.inv_mass + b.inv_mass) * k22 + a.inv_inertia * b.inv_inertia * ds * ds;
  if (det == 0.0) return;
  double inv_det = 1.0 / det;
  double r1 = cd1 + bias1, r2 = cd2 + bias2;
  double x1 = -ms * inv_det * (k22 * r1 - k12 * r2) - is * j.linear_impulse.x();
  double x2 = -ms * inv_det * (k11 * r2 - k12 * r1) - is * j.linear_impulse.y();
  j.linear_impulse += Vec2(x1, x2);
  double qx = x1 * px, qy = x1 * py;
  double la = x1 * fr.s1 + x2, lb = x1 * fr.s2 + x2;
  a.vx -= a.inv_mass * qx;
  a.vy -= a.inv_mass * qy;
  a.w -= a.inv_inertia * la;
  b.vx += b.inv_mass * qx;
  b.vy += b.inv_mass * qy;
  b.w += b.inv_inertia * lb;
}

}  // namespace fulcrum
