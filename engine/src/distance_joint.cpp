// Distance joint: keeps |pb - pa| in [min_length, max_length], with an optional spring toward
// `length` (Catto, "Modeling and Solving Constraints": the rod and the rope).
//   C = |d| - L with d = (cb + rb) - (ca + ra),  u = d / |d|
//   dC/dt = u . (vb + wb x rb - va - wa x ra),  J = [-u, -(ra x u), u, rb x u]
//   m_c = 1 / (ma + mb + ia (ra x u)^2 + ib (rb x u)^2)
// A rod (min = max) is one equality row. Otherwise the spring is a soft row toward `length`,
// and the limits are inequality rows: length - min >= 0 (lower) and max - length >= 0 (upper),
// speculative while not reached (a slack rope pulls nothing). The rod's and the limits' feedback
// closes no faster than max_correction_speed (joint_solver.h); the spring is not capped.
#include <algorithm>
#include <cmath>

#include "joint_solver.h"
#include "world_impl.h"

namespace fulcrum {

namespace {

struct Axis {
  double ux, uy, length;
};

Axis axis_of(const JointFrame& f) {
  double len = std::sqrt(f.dx * f.dx + f.dy * f.dy);
  if (len < 1e-12) return Axis{1.0, 0.0, len};  // coincident anchors: any axis will do
  return Axis{f.dx / len, f.dy / len, len};
}

// Applies impulse `lambda` along u: -P to A at ra, +P to B at rb.
void apply_axis(const JointFrame& f, const Axis& u, double lambda, ScalarBody& a, ScalarBody& b) {
  apply_joint_impulse(f, lambda * u.ux, lambda * u.uy, a, b);
}

double axis_speed(const JointFrame& f, const Axis& u, const ScalarBody& a, const ScalarBody& b) {
  double dvx = (b.vx - b.w * f.rby) - (a.vx - a.w * f.ray);
  double dvy = (b.vy + b.w * f.rbx) - (a.vy + a.w * f.rax);
  return dvx * u.ux + dvy * u.uy;
}

}  // namespace

void prepare_distance_joint(const Joint& j, JointRow& r, const ScalarBody& a, const ScalarBody& b) {
  JointFrame f = joint_frame(r, a, b);
  Axis u = axis_of(f);
  double cra = r.rax * u.uy - r.ray * u.ux, crb = r.rbx * u.uy - r.rby * u.ux;
  double k = a.inv_mass + b.inv_mass + a.inv_inertia * cra * cra + b.inv_inertia * crb * crb;
  r.axial_mass = k > 0.0 ? 1.0 / k : 0.0;
  (void)j;
}

void warm_start_distance_joint(const Joint& j, const JointRow& r, ScalarBody& a, ScalarBody& b) {
  JointFrame f = joint_frame(r, a, b);
  Axis u = axis_of(f);
  apply_axis(f, u, j.axial_impulse + j.spring_impulse + j.lower_impulse - j.upper_impulse, a, b);
}

void solve_distance_joint(Joint& j, const JointRow& r, const JointStep& st, ScalarBody& a,
                          ScalarBody& b) {
  JointFrame f = joint_frame(r, a, b);
  Axis u = axis_of(f);
  double bias, ms, is;
  if (j.min_length == j.max_length) {
    // A rod: one equality row.
    joint_bias(st, r.soft, u.length - j.length, &bias, &ms, &is);
    double cdot = axis_speed(f, u, a, b);
    double lambda = -ms * r.axial_mass * (cdot + bias) - is * j.axial_impulse;
    lambda =
        capped_row_impulse(st, lambda, r.axial_mass, cdot, bias, ms, is, j.axial_impulse, false);
    j.axial_impulse += lambda;
    apply_axis(f, u, lambda, a, b);
    return;
  }
  if (j.hertz > 0.0) {
    double c = u.length - j.length;
    double lambda =
        -r.spring.mass_scale * r.axial_mass * (axis_speed(f, u, a, b) + r.spring.bias_rate * c) -
        r.spring.impulse_scale * j.spring_impulse;
    j.spring_impulse += lambda;
    apply_axis(f, u, lambda, a, b);
  }
  // Lower limit: length - min >= 0 pushes apart.
  if (j.min_length > 0.0) {
    double c = u.length - j.min_length;
    limit_bias(st, r.soft, c, &bias, &ms, &is);
    double cdot = axis_speed(f, u, a, b);
    double lambda = -ms * r.axial_mass * (cdot + bias) - is * j.lower_impulse;
    lambda =
        capped_row_impulse(st, lambda, r.axial_mass, cdot, bias, ms, is, j.lower_impulse, true);
    double acc = std::max(j.lower_impulse + lambda, 0.0);
    lambda = acc - j.lower_impulse;
    j.lower_impulse = acc;
    apply_axis(f, u, lambda, a, b);
  }
  // Upper limit: max - length >= 0 pulls together (a taut rope).
  {
    double c = j.max_length - u.length;
    limit_bias(st, r.soft, c, &bias, &ms, &is);
    double cdot = -axis_speed(f, u, a, b);
    double lambda = -ms * r.axial_mass * (cdot + bias) - is * j.upper_impulse;
    lambda =
        capped_row_impulse(st, lambda, r.axial_mass, cdot, bias, ms, is, j.upper_impulse, true);
    double acc = std::max(j.upper_impulse + lambda, 0.0);
    lambda = acc - j.upper_impulse;
    j.upper_impulse = acc;
    apply_axis(f, u, -lambda, a, b);
  }
}

}  // namespace fulcrum
