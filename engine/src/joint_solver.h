// Per-step joint data and the functions each joint type provides to the solver. The joints
// themselves (with their accumulated impulses) live in WorldImpl::joints; a JointRow holds
// what one tick's substeps need.
#pragma once

#include "contact_solver.h"

namespace fulcrum {

struct Joint;

struct JointRow {
  int joint = -1;
  int ia = 0, ib = 0;           // solver body slots (0: the shared static body)
  double rax = 0.0, ray = 0.0;  // anchors relative to the centres of mass, tick start, world
  double rbx = 0.0, rby = 0.0;
  double dcx = 0.0, dcy = 0.0;        // centre of B minus centre of A, tick start
  double angle = 0.0;                 // revolute, weld, prismatic: joint angle at tick start
  double axis_x = 0.0, axis_y = 0.0;  // prismatic: slide axis, world, tick start
  double axial_mass = 0.0;            // distance: along the axis; revolute: 1 / (iA + iB)
  Softness soft;                      // position feedback
  Softness spring;                    // the joint's own spring (weld: linear part)
  Softness angular_spring;            // weld: angular part
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

inline JointFrame joint_frame(const JointRow& r, const SolverBody& a, const SolverBody& b) {
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
inline void apply_joint_impulse(const JointFrame& f, double px, double py, SolverBody& a,
                                SolverBody& b) {
  a.vx -= a.inv_mass * px;
  a.vy -= a.inv_mass * py;
  a.w -= a.inv_inertia * (f.rax * py - f.ray * px);
  b.vx += b.inv_mass * px;
  b.vy += b.inv_mass * py;
  b.w += b.inv_inertia * (f.rbx * py - f.rby * px);
}

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

void prepare_distance_joint(const Joint& j, JointRow& r, const SolverBody& a, const SolverBody& b);
void warm_start_distance_joint(const Joint& j, const JointRow& r, SolverBody& a, SolverBody& b);
void solve_distance_joint(Joint& j, const JointRow& r, const JointStep& st, SolverBody& a,
                          SolverBody& b);

void warm_start_weld_joint(const Joint& j, const JointRow& r, SolverBody& a, SolverBody& b);
void solve_weld_joint(Joint& j, const JointRow& r, const JointStep& st, SolverBody& a,
                      SolverBody& b);

void warm_start_target_joint(const Joint& j, const JointRow& r, SolverBody& b);
void solve_target_joint(Joint& j, const JointRow& r, const JointStep& st, SolverBody& b);

void warm_start_prismatic_joint(const Joint& j, const JointRow& r, SolverBody& a, SolverBody& b);
void solve_prismatic_joint(Joint& j, const JointRow& r, const JointStep& st, SolverBody& a,
                           SolverBody& b);

void prepare_revolute_joint(const Joint& j, JointRow& r, const SolverBody& a, const SolverBody& b);
void warm_start_revolute_joint(const Joint& j, const JointRow& r, SolverBody& a, SolverBody& b);
void solve_revolute_joint(Joint& j, const JointRow& r, const JointStep& st, SolverBody& a,
                          SolverBody& b);

}  // namespace fulcrum
