// Target joint: a soft point constraint between a point of body B and a world target, with
// the accumulated impulse capped at max_force h (dragging things around).
//   C = (cb + rb) - target,  dC/dt = vb + wb x rb,  K = mb I + ib [rb.y^2, -rb.x rb.y; ., rb.x^2]
// Always soft (the joint's own spring); body A only names the frame and takes no reaction.
#include <cmath>

#include "joint_solver.h"
#include "world_impl.h"

namespace fulcrum {

namespace {

void apply_to_b(double rbx, double rby, double px, double py, ScalarBody& b) {
  b.vx += b.inv_mass * px;
  b.vy += b.inv_mass * py;
  b.w += b.inv_inertia * (rbx * py - rby * px);
}

}  // namespace

void warm_start_target_joint(const Joint& j, const JointRow& r, ScalarBody& b) {
  double rbx = b.qc * r.rbx - b.qs * r.rby, rby = b.qs * r.rbx + b.qc * r.rby;
  apply_to_b(rbx, rby, j.linear_impulse.x(), j.linear_impulse.y(), b);
}

void solve_target_joint(Joint& j, const JointRow& r, const JointStep& st, ScalarBody& b) {
  double rbx = b.qc * r.rbx - b.qs * r.rby, rby = b.qs * r.rbx + b.qc * r.rby;
  double cdx = b.vx - b.w * rby, cdy = b.vy + b.w * rbx;
  // r.dcx, r.dcy hold centre of B minus the target at the start of the tick.
  double sx = r.dcx + b.dpx + rbx, sy = r.dcy + b.dpy + rby;
  double k11 = b.inv_mass + b.inv_inertia * rby * rby;
  double k12 = -b.inv_inertia * rbx * rby;
  double k22 = b.inv_mass + b.inv_inertia * rbx * rbx;
  double det = k11 * k22 - k12 * k12;
  if (det == 0.0) return;
  double inv_det = 1.0 / det;
  double rx = cdx + r.spring.bias_rate * sx, ry = cdy + r.spring.bias_rate * sy;
  double px = -r.spring.mass_scale * inv_det * (k22 * rx - k12 * ry) -
              r.spring.impulse_scale * j.linear_impulse.x();
  double py = -r.spring.mass_scale * inv_det * (k11 * ry - k12 * rx) -
              r.spring.impulse_scale * j.linear_impulse.y();
  Vec2 old = j.linear_impulse;
  Vec2 acc = old + Vec2(px, py);
  double limit = j.max_force * st.h;
  double size = length(acc);
  if (size > limit) acc *= limit / size;
  j.linear_impulse = acc;
  apply_to_b(rbx, rby, acc.x() - old.x(), acc.y() - old.y(), b);
}

}  // namespace fulcrum
