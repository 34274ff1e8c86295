// Curve joint: a bead on a wire (Catto, "Modeling and Solving Constraints", the first
// example). A point p = cb + rb of body B stays on a curve fixed in the world; it slides along
// the curve and turns freely, without friction.
//   C = n . (p - q),  q the closest curve point to p, n the unit curve normal at q
//   dC/dt = n . (vb + wb x rb)  (the curve does not move; q slides with p, and n . dq/dt = 0)
//   J = [n, rb x n] on body B,  m = 1 / (mb + ib (rb x n)^2)
// q and n are found again in every pass from B's current position, so the row follows the
// curve's bends. Polylines take the nearest segment (the first on ties); past a vertex the
// normal turns with p - q, so the bead passes a corner smoothly. Body A only names the frame.
// The feedback closes no faster than max_correction_speed (joint_solver.h).
#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "joint_solver.h"
#include "validation.h"
#include "world_impl.h"

namespace fulcrum {

Status validate_curve_joint_def(const CurveJointDef& d) {
  FULCRUM_RETURN_IF_ERROR(check_finite("joint.local_anchor_b", d.local_anchor_b));
  switch (d.curve) {
    case CurveType::kLine:
      FULCRUM_RETURN_IF_ERROR(check_finite("joint.point", d.point));
      FULCRUM_RETURN_IF_ERROR(check_finite("joint.direction", d.direction));
      if (length(d.direction) < 1e-9) {
        return invalid_argument("joint.direction: must not be zero");
      }
      return {};
    case CurveType::kCircle:
      FULCRUM_RETURN_IF_ERROR(check_finite("joint.point", d.point));
      return check_above("joint.radius", d.radius, 0.0);
    case CurveType::kPolyline:
      if (d.points.size() < 2) {
        return invalid_argument("joint.points: a polyline needs at least 2 points (got " +
                                std::to_string(d.points.size()) + ")");
      }
      for (size_t i = 0; i < d.points.size(); ++i) {
        std::string field = "joint.points[" + std::to_string(i) + "]";
        FULCRUM_RETURN_IF_ERROR(check_finite(field, d.points[i]));
        if (i > 0 && distance(d.points[i], d.points[i - 1]) < 1e-9) {
          return invalid_argument(field + ": must differ from the point before it");
        }
      }
      return {};
  }
  return invalid_argument("joint.curve: unknown curve type " +
                          std::to_string(static_cast<int>(d.curve)));
}

Result<JointId> World::create_curve_joint(const CurveJointDef& def) {
  FULCRUM_RETURN_IF_ERROR(validate_curve_joint_def(def));
  int a = impl_->body_index(def.body_a);
  if (a != kNullIndex && impl_->bodies[a].type != BodyType::kStatic) {
    return invalid_argument("joint.body_a: must be a static body (the curve's frame)");
  }
  Result<int> ji = impl_->add_joint(JointType::kCurve, def.body_a, def.body_b, true);
  if (!ji.ok()) return ji.status();
  Joint& j = impl_->joints[*ji];
  j.local_b = def.local_anchor_b;
  j.curve_type = def.curve;
  switch (def.curve) {
    case CurveType::kLine:
      j.curve_points = {def.point, normalize_or_zero(def.direction)};
      break;
    case CurveType::kCircle:
      j.curve_points = {def.point};
      j.curve_radius = def.radius;
      break;
    case CurveType::kPolyline:
      j.curve_points = def.points;
      break;
  }
  return impl_->joint_id(*ji);
}

CurvePoint closest_on_curve(const Joint& j, const Vec2& p) {
  CurvePoint out;
  const std::vector<Vec2>& pts = j.curve_points;
  if (j.curve_type == CurveType::kLine) {
    const Vec2& u = pts[1];
    out.closest = pts[0] + dot(p - pts[0], u) * u;
    out.normal = left_perp(u);
  } else if (j.curve_type == CurveType::kCircle) {
    Vec2 d = p - pts[0];
    double len = length(d);
    out.normal = len > 1e-12 ? Vec2(d / len) : Vec2(1.0, 0.0);  // the centre: any direction
    out.closest = pts[0] + j.curve_radius * out.normal;
  } else {
    double best = std::numeric_limits<double>::infinity(), best_t = 0.0;
    size_t best_k = 0;
    for (size_t k = 0; k + 1 < pts.size(); ++k) {
      Vec2 e = pts[k + 1] - pts[k];
      double t = std::clamp(dot(p - pts[k], e) / dot(e, e), 0.0, 1.0);
      Vec2 q = pts[k] + t * e;
      double d2 = distance_squared(p, q);
      if (d2 < best) {
        best = d2;
        best_t = t;
        best_k = k;
        out.closest = q;
      }
    }
    Vec2 e = pts[best_k + 1] - pts[best_k];
    Vec2 side = left_perp(e) / length(e);
    out.normal = side;
    Vec2 d = p - out.closest;
    double len = length(d);
    if ((best_t == 0.0 || best_t == 1.0) && len > 1e-12) {
      // At a vertex: along p - q, on the segment's side.
      out.normal = dot(d, side) < 0.0 ? Vec2(-d / len) : Vec2(d / len);
    }
  }
  return out;
}

namespace {

// The bead now, world, and its arm from B's centre of mass.
Vec2 bead(const JointRow& r, const ScalarBody& b, double* rbx, double* rby) {
  *rbx = b.qc * r.rbx - b.qs * r.rby;
  *rby = b.qs * r.rbx + b.qc * r.rby;
  // r.dcx, r.dcy hold B's centre of mass at the start of the tick, world.
  return Vec2(r.dcx + b.dpx + *rbx, r.dcy + b.dpy + *rby);
}

void apply_normal(double lambda, const Vec2& n, double crn, ScalarBody& b) {
  b.vx += b.inv_mass * (lambda * n.x());
  b.vy += b.inv_mass * (lambda * n.y());
  b.w += b.inv_inertia * (lambda * crn);
}

}  // namespace

void warm_start_curve_joint(const Joint& j, const JointRow& r, ScalarBody& b) {
  double rbx, rby;
  CurvePoint cp = closest_on_curve(j, bead(r, b, &rbx, &rby));
  apply_normal(j.axial_impulse, cp.normal, rbx * cp.normal.y() - rby * cp.normal.x(), b);
}

void solve_curve_joint(Joint& j, const JointRow& r, const JointStep& st, ScalarBody& b) {
  double rbx, rby;
  Vec2 p = bead(r, b, &rbx, &rby);
  CurvePoint cp = closest_on_curve(j, p);
  const Vec2& n = cp.normal;
  double crn = rbx * n.y() - rby * n.x();
  double k = b.inv_mass + b.inv_inertia * crn * crn;
  if (k == 0.0) return;
  double cdot = n.x() * (b.vx - b.w * rby) + n.y() * (b.vy + b.w * rbx);
  double bias, ms, is;
  joint_bias(st, r.soft, dot(n, p - cp.closest), &bias, &ms, &is);
  double lambda = -ms * (cdot + bias) / k - is * j.axial_impulse;
  lambda = capped_row_impulse(st, lambda, 1.0 / k, cdot, bias, ms, is, j.axial_impulse, false);
  j.axial_impulse += lambda;
  apply_normal(lambda, n, crn, b);
}

}  // namespace fulcrum
