// Applied forces beyond gravity that are world state: constant forces on bodies (every tick
// until changed) and attractors (a pull toward a point). Both are integrated with gravity, in
// integrate_velocities (contact_solver.cpp), every substep:
//   v2 = v1 + h (M^-1 (F_tick + F_constant) + gravity_scale g + a_attractors(x))
// where x is the centre of mass at the substep's start (explicit, like the spring forces).
// Attractor i pulls with
//   |a| = s (constant)  or  s / d^2 (inverse square),  d = |p_i - x|, d >= min_distance,
//   |a| scaled by d / min_distance when d < min_distance (zero at the point itself),
// along (p_i - x) / d; s is an acceleration (per_mass) or a force (divided by the mass). The
// attractors are summed in the world's order, so the result does not depend on threads.
#include <cmath>
#include <string>

#include "validation.h"
#include "world_impl.h"

namespace fulcrum {

Vec2 WorldImpl::attraction(const Body& b, const Vec2& x) const {
  uint64_t categories = 0;
  for (int si : b.shapes) categories |= shapes[si].filter.category_bits;
  double ax = 0.0, ay = 0.0;
  for (const AttractorDef& a : attractors) {
    if ((categories & a.mask_bits) == 0) continue;
    const double dx = a.point.x() - x.x(), dy = a.point.y() - x.y();
    const double d = std::sqrt(dx * dx + dy * dy);
    if (d == 0.0) continue;  // at the point: no direction, and the pull is zero there anyway
    const double r = d < a.min_distance ? a.min_distance : d;
    double size = a.falloff == Falloff::kInverseSquare ? a.strength / (r * r) : a.strength;
    if (d < a.min_distance) size *= d / a.min_distance;
    if (!a.per_mass) size *= b.inv_mass;
    const double k = size / d;
    ax += k * dx;
    ay += k * dy;
  }
  return Vec2(ax, ay);
}

Status World::set_constant_force(BodyId id, const Vec2& force, double torque) {
  WorldImpl& w = *impl_;
  int bi = w.body_index(id);
  if (bi == kNullIndex) {
    return not_found("body {" + std::to_string(id.index) + ", " + std::to_string(id.generation) +
                     "}: unknown or destroyed body handle");
  }
  FULCRUM_RETURN_IF_ERROR(check_finite("force", force));
  FULCRUM_RETURN_IF_ERROR(check_finite("torque", torque));
  Body& b = w.bodies[bi];
  if (!b.is_dynamic()) return {};
  b.constant_force = force;
  b.constant_torque = b.rotates() ? torque : 0.0;
  if (force != Vec2::Zero() || torque != 0.0) w.wake_island(bi);
  return {};
}

Status World::set_attractors(const std::vector<AttractorDef>& attractors) {
  for (size_t i = 0; i < attractors.size(); ++i) {
    FULCRUM_RETURN_IF_ERROR(
        validate_attractor(attractors[i], "attractors[" + std::to_string(i) + "]"));
  }
  impl_->attractors = attractors;
  return {};
}

const std::vector<AttractorDef>& World::attractors() const {
  return impl_->attractors;
}

}  // namespace fulcrum
