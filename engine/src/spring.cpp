// Spring force elements between two body points: applied forces, not constraints (MISSION.md:
// "springs F = -k x ... are integrated first"). Each substep, with the velocities integrated:
//   d = anchor B - anchor A,  u = d / |d|,  v = u . (vb + wb x rb - va - wa x ra)
//   f = -(stiffness (|d| - rest_length) + damping v),  impulse h f u on B at rb, -h f u on A
// Explicit (symplectic Euler with the position update that follows), so stable while
// h sqrt(k / m) < 2; applied once per substep, so it costs less than a constraint row that
// every iteration visits. Springs ride the joint list: islands, waking,
// break limits and destruction with a body come for free.
#include <cmath>
#include <cstdio>
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

namespace {

// The explicit update of one spring on its own, with m the effective mass along the spring and
// h the substep: v' = v - h (k x + c v) / m, x' = x + h v'. Its matrix has determinant 1 - a
// and trace 2 - a - b (a = h c / m, b = h^2 k / m), so it is stable while b + 2 a < 4.
// 1 / m = sum over both bodies of inv_mass + inv_inertia |r|^2 (r: anchor from the centre of
// mass) is the least effective mass the spring meets as the bodies turn (each anchor arm at
// right angles to it). Checked against the bodies and settings at creation.
Status check_spring_stability(const WorldImpl& w, const SpringDef& d) {
  int a = w.body_index(d.body_a), b = w.body_index(d.body_b);
  if (a == kNullIndex || b == kNullIndex) return {};  // add_joint names the bad body
  auto inv_mass = [&](int bi, const Vec2& local_anchor) {
    const Body& body = w.bodies[bi];
    Vec2 r = local_anchor - body.local_center;
    return body.inv_mass + body.inv_inertia * dot(r, r);
  };
  const double inv_m = inv_mass(a, d.local_anchor_a) + inv_mass(b, d.local_anchor_b);
  const double h = w.settings.dt / w.settings.substeps;
  const double damping_term = 2.0 * h * d.damping * inv_m;
  const double stiffness_term = h * h * d.stiffness * inv_m;
  if (damping_term + stiffness_term < 4.0) return {};
  auto brief = [](double x) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.4g", x);
    return std::string(buf);
  };
  const double m = 1.0 / inv_m;
  const std::string why =
      " for the explicit update to be stable at this world's substep (h = " + brief(h) +
      " s, effective mass " + brief(m) + " kg";
  if (damping_term >= 4.0) {
    return invalid_argument("spring.damping: must be < " + brief(2.0 * m / h) + " N s/m" + why +
                            ") (got " + format_number(d.damping) + ")");
  }
  return invalid_argument(
      "spring.stiffness: must be < " + brief((4.0 - damping_term) * m / (h * h)) + " N/m" + why +
      ", damping " + format_number(d.damping) + " N s/m) (got " + format_number(d.stiffness) + ")");
}

}  // namespace

Result<JointId> World::create_spring(const SpringDef& def) {
  FULCRUM_RETURN_IF_ERROR(validate_spring_def(def));
  FULCRUM_RETURN_IF_ERROR(check_spring_stability(*impl_, def));
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

void apply_spring_force(Joint& j, const JointRow& r, double h, ScalarBody& a, ScalarBody& b) {
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
    ScalarBody a = scalar_body(s, r.ia), b = scalar_body(s, r.ib);
    apply_spring_force(joints[r.joint], r, h, a, b);
    store_velocity(a, s.bodies[r.ia]);
    store_velocity(b, s.bodies[r.ib]);
  }
}

}  // namespace fulcrum
