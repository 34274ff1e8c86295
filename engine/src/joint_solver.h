// Per-step joint data and the functions each joint type provides to the solver. The joints
// themselves (with their accumulated impulses) live in WorldImpl::joints; a JointRow holds
// what one tick's substeps need.
#pragma once

#include <cmath>

#include "contact_solver.h"
#include "fulcrum/joints.h"
#include "fulcrum/math.h"

namespace fulcrum {

struct Joint;

// A revolute joint's angle rows for one tick: its settings and accumulated impulses, copied from
// the Joint when the row is filled, into its lane (joint_lanes.h), and written back after the
// tick (store_joint_impulses).
struct RevoluteRow {
  bool spring = false, motor = false, limit = false;  // enable_spring, _motor, _limit
  double target_angle = 0.0;
  double motor_speed = 0.0, max_motor_torque = 0.0;
  double lower_angle = 0.0, upper_angle = 0.0;
  double spring_impulse = 0.0, motor_impulse = 0.0;
  double lower_impulse = 0.0, upper_impulse = 0.0;
};

// A plain pin's row (plain_point) is the fields up to `soft` alone: prepare_joints writes
// only those, and nothing reads the rest of such a row (a joint grid's rows are mostly pins).
// On a tick that keeps the last tick's layout of the pins (joint_lanes.h, place_point) a pin's
// row is written into its lane and not kept: only the other rows are in joint_rows then.
struct JointRow {
  int joint = -1;
  int ia = 0, ib = 0;  // solver body slots (0: the shared static body)
  JointType type = JointType::kDistance;
  // A revolute joint that is only its point (no limit, motor or spring, and no impulse left
  // on those rows): solved in lanes (joint_lanes.h), which keep its point impulse for the tick
  // so that the passes never touch the large Joint record.
  bool plain_point = false;
  double rax = 0.0, ray = 0.0;  // anchors relative to the centres of mass, tick start, world
  double rbx = 0.0, rby = 0.0;
  double dcx = 0.0, dcy = 0.0;  // centre of B minus centre of A, tick start
  // A revolute joint's accumulated point impulse: a plain point's at tick start; the other
  // revolute rows keep it (and `revolute`) up to date through the tick.
  double ix = 0.0, iy = 0.0;
  Softness soft;                      // position feedback
  double angle = 0.0;                 // revolute, weld, prismatic: joint angle at tick start
  double axis_x = 0.0, axis_y = 0.0;  // prismatic: slide axis, world, tick start
  double axial_mass = 0.0;            // distance: along the axis; revolute: 1 / (iA + iB)
  Softness spring;                    // the joint's own spring (weld: linear part)
  Softness angular_spring;            // weld: angular part
  RevoluteRow revolute;
};

// Context shared by every joint row of one substep.
struct JointStep {
  double h = 0.0;  // substep
  double inv_h = 0.0;
  bool use_bias = true;  // position feedback in this pass
  bool rigid = false;    // rigid Baumgarte feedback instead of soft
  double baumgarte = 0.2;
  double max_speed = 1.5;  // cap on push-out speed
};

// Current anchors (turned with the bodies) and the vector between them.
struct JointFrame {
  double rax, ray, rbx, rby;
  double dx, dy;  // anchor B minus anchor A, now
};

inline JointFrame joint_frame(const JointRow& r, const ScalarBody& a, const ScalarBody& b) {
  JointFrame f;
  f.rax = a.qc * r.rax - a.qs * r.ray;
  f.ray = a.qs * r.rax + a.qc * r.ray;
  f.rbx = b.qc * r.rbx - b.qs * r.rby;
  f.rby = b.qs * r.rbx + b.qc * r.rby;
  f.dx = (r.dcx + (b.dpx - a.dpx)) + (f.rbx - f.rax);
  f.dy = (r.dcy + (b.dpy - a.dpy)) + (f.rby - f.ray);
  return f;
}

// P applied to B at its anchor and -P to A at its anchor.
inline void apply_joint_impulse(const JointFrame& f, double px, double py, ScalarBody& a,
                                ScalarBody& b) {
  a.vx -= a.inv_mass * px;
  a.vy -= a.inv_mass * py;
  a.w -= a.inv_inertia * (f.rax * py - f.ray * px);
  b.vx += b.inv_mass * px;
  b.vy += b.inv_mass * py;
  b.w += b.inv_inertia * (f.rbx * py - f.rby * px);
}

// A line joint's frame (prismatic, wheel): axis u fixed in body A, d = anchor B - anchor A.
//   along u:  J = [-u, -(d + ra) x u, u, rb x u]   (a1 = (d + ra) x u, a2 = rb x u)
//   along p = perp(u):  J = [-p, -(d + ra) x p, p, rb x p]   (s1, s2 likewise)
struct LineFrame {
  JointFrame f;
  double ux, uy;  // axis now
  double a1, a2;  // (d + ra) x u and rb x u
  double s1, s2;  // (d + ra) x p and rb x p, p = (-uy, ux)
};

inline LineFrame line_frame(const JointRow& r, const ScalarBody& a, const ScalarBody& b) {
  LineFrame fr;
  fr.f = joint_frame(r, a, b);
  fr.ux = a.qc * r.axis_x - a.qs * r.axis_y;
  fr.uy = a.qs * r.axis_x + a.qc * r.axis_y;
  double dax = fr.f.dx + fr.f.rax, day = fr.f.dy + fr.f.ray;
  fr.a1 = dax * fr.uy - day * fr.ux;
  fr.a2 = fr.f.rbx * fr.uy - fr.f.rby * fr.ux;
  double px = -fr.uy, py = fr.ux;
  fr.s1 = dax * py - day * px;
  fr.s2 = fr.f.rbx * py - fr.f.rby * px;
  return fr;
}

// Impulse along the axis: P = lambda u at the anchors (angular parts a1, a2).
inline void apply_line_axial(const LineFrame& fr, double lambda, ScalarBody& a, ScalarBody& b) {
  double px = lambda * fr.ux, py = lambda * fr.uy;
  a.vx -= a.inv_mass * px;
  a.vy -= a.inv_mass * py;
  a.w -= a.inv_inertia * (lambda * fr.a1);
  b.vx += b.inv_mass * px;
  b.vy += b.inv_mass * py;
  b.w += b.inv_inertia * (lambda * fr.a2);
}

inline double line_axial_speed(const LineFrame& fr, const ScalarBody& a, const ScalarBody& b) {
  return fr.ux * (b.vx - a.vx) + fr.uy * (b.vy - a.vy) + fr.a2 * b.w - fr.a1 * a.w;
}

inline double line_axial_mass(const LineFrame& fr, const ScalarBody& a, const ScalarBody& b) {
  double k =
      a.inv_mass + b.inv_mass + a.inv_inertia * fr.a1 * fr.a1 + b.inv_inertia * fr.a2 * fr.a2;
  return k > 0.0 ? 1.0 / k : 0.0;
}

// The translation limits of a line joint along its axis (lower <= t <= upper), as two
// inequality rows, speculative until reached. Shared by prismatic and wheel joints.
void solve_line_limits(Joint& j, const LineFrame& fr, double m, const JointRow& r,
                       const JointStep& st, ScalarBody& a, ScalarBody& b);

// The feedback for position error C of a joint row in this pass: bias, mass and impulse
// scales (see contact_solver.cpp for the soft form).
inline void joint_bias(const JointStep& st, const Softness& soft, double c, double* bias,
                       double* mass_scale, double* impulse_scale) {
  *bias = 0.0;
  *mass_scale = 1.0;
  *impulse_scale = 0.0;
  if (!st.use_bias) return;
  if (st.rigid) {
    *bias = st.baumgarte * st.inv_h * c;
    return;
  }
  *bias = soft.bias_rate * c;
  *mass_scale = soft.mass_scale;
  *impulse_scale = soft.impulse_scale;
}

// The feedback of an inequality row (a limit) with position error c: while apart (c > 0) it is
// speculative, the gap closed in one substep with no softness; once reached, the joint's.
inline void limit_bias(const JointStep& st, const Softness& soft, double c, double* bias,
                       double* mass_scale, double* impulse_scale) {
  if (c > 0.0) {
    *bias = c * st.inv_h;
    *mass_scale = 1.0;
    *impulse_scale = 0.0;
  } else {
    joint_bias(st, soft, c, bias, mass_scale, impulse_scale);
  }
}

// Joint position feedback is capped at WorldSettings::max_correction_speed, as the contacts'
// push-out is, on the speed a row asks its error to close at. A row's impulse
//   lambda = -ms m (Jv + bias) - is acc  =  -ms m (Jv + B),   B = bias + is acc / (ms m)
// drives Jv toward -B: the feedback's pull (bias = rate C) less the softness's give under the
// load the row carries (is acc / (ms m)). Under a steady load B is zero, whatever error holds
// the load, so the cap never weakens a loaded joint. Capping `bias` alone would: a soft row at
// rest needs bias = is acc / (ms m), about 5 m/s in the joint above a 1000:1 end mass at the
// defaults, and a joint whose load needs more than the cap would stretch without end. So only
// a joint that is far out of place (created apart, pulled apart, a body teleported) closes at
// the cap, where it used to close at rate * C (60 m/s for 1 m at the defaults), flinging
// whatever it holds. Equality rows cap both ways; inequality rows (limits) only the push-out
// (B >= -cap): their positive B is the speculative allowance c / h, not feedback. Linear rows
// only: the cap is a speed in m/s, and an angle row's feedback is bounded by its angle error.

// `lambda` is a linear row's impulse as written above, m its effective mass, acc its
// accumulated impulse; returns lambda with B capped (unchanged within the cap).
inline double capped_row_impulse(const JointStep& st, double lambda, double m, double cdot,
                                 double bias, double ms, double is, double acc, bool one_sided) {
  if (!st.use_bias || !(m > 0.0)) return lambda;
  const double pull = ms * m * bias + is * acc;  // ms m B, compared without dividing
  const double cap = ms * m * st.max_speed;
  if (pull < -cap) return cap - ms * m * cdot;
  if (!one_sided && pull > cap) return -cap - ms * m * cdot;
  return lambda;
}

// The point rows' form (revolute, weld, motor-free two-row blocks): B = bias + (is / ms) K acc
// is a velocity; its length is capped. Returns the change to apply to the block's impulse
// (ms K^-1 (B - B_capped), in terms of inv_det and K), zero within the cap.
inline Vec2 capped_point_correction(const JointStep& st, double k11, double k12, double k22,
                                    double inv_det, double bias_x, double bias_y, double ms,
                                    double is, const Vec2& acc) {
  if (!st.use_bias) return Vec2::Zero();
  const double tx = ms * bias_x + is * (k11 * acc.x() + k12 * acc.y());  // ms B
  const double ty = ms * bias_y + is * (k12 * acc.x() + k22 * acc.y());
  const double cap = ms * st.max_speed;
  const double t2 = tx * tx + ty * ty;
  if (!(t2 > cap * cap)) return Vec2::Zero();
  const double f = 1.0 - cap / std::sqrt(t2);  // ms (B - B_capped) = f ms B
  const double dx = f * tx, dy = f * ty;
  return Vec2(inv_det * (k22 * dx - k12 * dy), inv_det * (k11 * dy - k12 * dx));
}

void prepare_distance_joint(const Joint& j, JointRow& r, const ScalarBody& a, const ScalarBody& b);
void warm_start_distance_joint(const Joint& j, const JointRow& r, ScalarBody& a, ScalarBody& b);
void solve_distance_joint(Joint& j, const JointRow& r, const JointStep& st, ScalarBody& a,
                          ScalarBody& b);

void warm_start_weld_joint(const Joint& j, const JointRow& r, ScalarBody& a, ScalarBody& b);
void solve_weld_joint(Joint& j, const JointRow& r, const JointStep& st, ScalarBody& a,
                      ScalarBody& b);

void warm_start_target_joint(const Joint& j, const JointRow& r, ScalarBody& b);
void solve_target_joint(Joint& j, const JointRow& r, const JointStep& st, ScalarBody& b);

void warm_start_prismatic_joint(const Joint& j, const JointRow& r, ScalarBody& a, ScalarBody& b);
void solve_prismatic_joint(Joint& j, const JointRow& r, const JointStep& st, ScalarBody& a,
                           ScalarBody& b);

void warm_start_wheel_joint(const Joint& j, const JointRow& r, ScalarBody& a, ScalarBody& b);
void solve_wheel_joint(Joint& j, const JointRow& r, const JointStep& st, ScalarBody& a,
                       ScalarBody& b);

void warm_start_motor_joint(const Joint& j, const JointRow& r, ScalarBody& a, ScalarBody& b);
void solve_motor_joint(Joint& j, const JointRow& r, const JointStep& st, ScalarBody& a,
                       ScalarBody& b);

// Curve joints: the closest point of the curve to p and the unit normal there, oriented
// consistently along the curve (line and polyline: to the left of the direction of travel;
// circle: outward), so that C = n . (p - closest) is a signed distance.
struct CurvePoint {
  Vec2 closest = Vec2::Zero();
  Vec2 normal = Vec2(0.0, 1.0);
};
CurvePoint closest_on_curve(const Joint& j, const Vec2& p);
void warm_start_curve_joint(const Joint& j, const JointRow& r, ScalarBody& b);
void solve_curve_joint(Joint& j, const JointRow& r, const JointStep& st, ScalarBody& b);

// Spring force elements: one substep's force, applied as the impulse h F.
void apply_spring_force(Joint& j, const JointRow& r, double h, ScalarBody& a, ScalarBody& b);

void prepare_revolute_joint(const Joint& j, JointRow& r, const ScalarBody& a, const ScalarBody& b);
// Every revolute joint is warm-started and solved in lanes (joint_lanes.h), from its row.

}  // namespace fulcrum
