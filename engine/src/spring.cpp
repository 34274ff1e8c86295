// Spring force elements between two body points: applied forces, not constraints (MISSION.md:
// "springs F = -k x ... are integrated first"). Each substep, with the velocities integrated:
//   d = anchor B - anchor A,  u = d / |d|,  v = u . (vb + wb x rb - va - wa x ra)
//   f = -(stiffness (|d| - rest_length) + damping v),  impulse h f u on B at rb, -h f u on A
// Explicit (symplectic Euler with the position update that follows), so stable while
// h sqrt(k / m) < 2; applied once per substep, so it costs less than a constraint row that
// every iteration visits. Springs ride the joint list: islands, waking,
// break limits and destruction with a body come for free.
#include <cmath>
#include <string>

#include "joint_solver.h"
#include "validation.h"
#include "world_impl.h"

namespace fulcrum {

Status validate_spring_def(const SpringDef& d) {
  FULCRUM_RETURN_IF_ERROR(check_finite("spring.local_anchor_a", d.local_anchor_a));
  FULCRUM_RETURN_IF_ERROR(check_finite("spring.local_anchor_b", d.local_anchor_b));
  FULCRUM_RETURN_IF_ERROR(check_non_negative("spring.rest_length", d.rest_length));
  FULCRUM_RETURN_IF_ERROR(check_non_negative("spring.stiffness", d.stiffness));
  FULCRUM_RETURN_IF_ERROR(check_non_negative("spring.damping", d.damping));
  return {};
}

Result<JointId> World::create_spring(const SpringDef& def) {
  FULCRUM_RETURN_IF_ERROR(validate_spring_def(def));
  Result<int> ji =
      impl_->add_joint(JointType::kSpring, def.body_a, def.body_b, def.collide_connected);
  if (!ji.ok()) {
    // The shared body checks name "joint."; this API calls it a spring.
    std::string msg = ji.status().message();
    if (msg.rfind("joint.", 0) == 0) msg = "spring." + msg.substr(6);
    return Status(ji.status().code(), msg);
  }
  Joint& j = impl_->joints[*ji];
  j.local_a = def.local_anchor_a;
  j.local_b = def.local_anchor_b;
  j.length = def.rest_length;
  j.stiffness = def.stiffness;
  j.damping = def.damping;
  return impl_->joint_id(*ji);
}

void apply_spring_force(Joint& j, const JointRow& r, double h, SolverBody& a, SolverBody& b) {
  JointFrame f = joint_frame(r, a, b);
  double len = std::sqrt(f.dx * f.dx + f.dy * f.dy);
  if (len < 1e-12) {
    j.spring_impulse = 0.0;  // coincident anchors: no direction to push along
    return;
  }
  double ux = f.dx / len, uy = f.dy / len;
  double dvx = (b.vx - b.w * f.rby) - (a.vx - a.w * f.ray);
  double dvy = (b.vy + b.w * f.rbx) - (a.vy + a.w * f.rax);
  double force = -(j.stiffness * (len - j.length) + j.damping * (dvx * ux + dvy * uy));
  j.spring_impulse = h * force;
  apply_joint_impulse(f, j.spring_impulse * ux, j.spring_impulse * uy, a, b);
}

void WorldImpl::apply_spring_forces(double h) {
  SolverScratch& s = solver_scratch;
  for (const JointRow& r : s.spring_rows) {
    apply_spring_force(joints[r.joint], r, h, s.bodies[r.ia], s.bodies[r.ib]);
  }
}

}  // namespace fulcrum
