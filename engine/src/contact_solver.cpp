// The sequential-impulse step for contacts (Catto, "Modeling and Solving Constraints", GDC 2009;
// "Iterative Dynamics with Temporal Coherence", 2005).
//
// Normal row of one contact point, with n the normal from A to B and r the point relative to
// each centre of mass:
//   C = separation >= 0,  dC/dt = J v = n . (vB + wB x rB - vA - wA x rA)
//   J = [-n, -(rA x n), n, rB x n],  m_c = 1 / (mA + mB + iA (rA x n)^2 + iB (rB x n)^2)
//   lambda = -m_c (J v - target),  accumulated impulse clamped to >= 0.
// target: s / h of approach allowed while separated by s > 0 (speculative contact), or the
// Baumgarte push-out (beta / h) * (-(s + slop)) while overlapping (on pseudo velocities when
// split impulses are on). Friction is a velocity motor along the tangent t with target 0,
// clamped to |lambda_t| <= mu * lambda_n. Restitution is applied once after the iterations to
// points that were approaching faster than the threshold and carried load.
#include <algorithm>
#include <cmath>

#include "fulcrum/trig.h"
#include "world_impl.h"

namespace fulcrum {

namespace {

inline double normal_speed(const SolverBody& a, const SolverBody& b, const ContactPointRow& p,
                           const Vec2& n) {
  Vec2 dv = b.v + cross(b.w, p.rb) - a.v - cross(a.w, p.ra);
  return dot(dv, n);
}

inline void apply_impulse(SolverBody& a, SolverBody& b, const ContactPointRow& p, const Vec2& P) {
  a.v -= a.inv_mass * P;
  a.w -= a.inv_inertia * cross(p.ra, P);
  b.v += b.inv_mass * P;
  b.w += b.inv_inertia * cross(p.rb, P);
}

// Gathers the awake, touching, solid contacts in id order.
void gather_contacts(WorldImpl& w, const std::vector<int>& awake, std::vector<int>* out) {
  out->clear();
  for (int bi : awake) {
    for (int e = w.bodies[bi].contact_list; e != kNullIndex;) {
      int ci = edge_contact(e);
      const Contact& c = w.contacts[ci];
      int other = edge_side(e) == 0 ? c.body_b : c.body_a;
      // Take each contact once: from its lower-indexed awake body.
      bool other_first = w.bodies[other].awake && other < bi;
      if (c.touching && !c.sensor && !other_first) out->push_back(ci);
      e = c.edges[edge_side(e)].next;
    }
  }
  std::sort(out->begin(), out->end());
}

void integrate_velocities(WorldImpl& w, const std::vector<int>& awake, SolverScratch& s) {
  const double h = w.settings.dt;
  const Vec2 g = w.settings.gravity;
  s.bodies.resize(awake.size() + 1);
  s.bodies[0] = SolverBody{};  // the shared static body: zero velocity, infinite mass
  if (s.body_slot.size() < w.bodies.size()) s.body_slot.resize(w.bodies.size(), 0);
  for (size_t k = 0; k < awake.size(); ++k) {
    Body& b = w.bodies[awake[k]];
    s.body_slot[awake[k]] = static_cast<int>(k + 1);
    SolverBody& sb = s.bodies[k + 1];
    sb.inv_mass = b.inv_mass;
    sb.inv_inertia = b.inv_inertia;
    sb.pv = Vec2::Zero();
    sb.pw = 0.0;
    if (b.is_dynamic()) {
      // Applied forces first (step 1): v2 = v1 + h M^-1 F, then damping as the exact decay
      // factor of a first-order Pade approximation, which stays stable for any damping.
      Vec2 v = b.v + h * (b.inv_mass * b.force + b.gravity_scale * g);
      double av = b.w + h * b.inv_inertia * b.torque;
      v *= 1.0 / (1.0 + h * b.linear_damping);
      av *= 1.0 / (1.0 + h * b.angular_damping);
      sb.v = v;
      sb.w = av;
    } else {
      sb.v = b.v;
      sb.w = b.w;
    }
  }
}

void prepare(WorldImpl& w, SolverScratch& s) {
  const WorldSettings& set = w.settings;
  const double inv_h = 1.0 / set.dt;
  s.rows.resize(s.contacts.size());
  for (size_t k = 0; k < s.contacts.size(); ++k) {
    const Contact& c = w.contacts[s.contacts[k]];
    const Body& body_a = w.bodies[c.body_a];
    const Body& body_b = w.bodies[c.body_b];
    ContactRow& row = s.rows[k];
    row.contact = s.contacts[k];
    row.ia = body_a.awake ? s.body_slot[c.body_a] : 0;
    row.ib = body_b.awake ? s.body_slot[c.body_b] : 0;
    row.normal = c.manifold.normal;
    row.friction = c.friction;
    row.restitution = c.restitution;
    row.count = c.manifold.count;
    const SolverBody& a = s.bodies[row.ia];
    const SolverBody& b = s.bodies[row.ib];
    const Vec2 n = row.normal;
    const Vec2 t = right_perp(n);
    for (int i = 0; i < row.count; ++i) {
      const ManifoldPoint& mp = c.manifold.points[i];
      ContactPointRow& p = row.points[i];
      p.ra = mp.point - body_a.center;
      p.rb = mp.point - body_b.center;
      double rna = cross(p.ra, n), rnb = cross(p.rb, n);
      double kn = a.inv_mass + b.inv_mass + a.inv_inertia * rna * rna + b.inv_inertia * rnb * rnb;
      p.normal_mass = kn > 0.0 ? 1.0 / kn : 0.0;
      double rta = cross(p.ra, t), rtb = cross(p.rb, t);
      double kt = a.inv_mass + b.inv_mass + a.inv_inertia * rta * rta + b.inv_inertia * rtb * rtb;
      p.tangent_mass = kt > 0.0 ? 1.0 / kt : 0.0;

      double sep = mp.separation;
      double push = std::min(set.baumgarte * inv_h * std::max(0.0, -(sep + set.linear_slop)),
                             set.max_correction_speed);
      if (sep > 0.0) {
        p.target = -sep * inv_h;  // may close the gap within this tick, no faster
        p.pseudo_target = 0.0;
      } else if (set.split_impulses) {
        p.target = 0.0;
        p.pseudo_target = push;
      } else {
        p.target = push;
        p.pseudo_target = 0.0;
      }
      p.approach_speed = normal_speed(a, b, p, n);
      p.normal_impulse = set.warm_starting ? mp.normal_impulse : 0.0;
      p.tangent_impulse = set.warm_starting ? mp.tangent_impulse : 0.0;
      p.pseudo_impulse = 0.0;
      p.max_normal_impulse = 0.0;
    }
    row.block = false;
    if (row.count == 2 && set.block_solver) {
      const ContactPointRow& p1 = row.points[0];
      const ContactPointRow& p2 = row.points[1];
      double rn1a = cross(p1.ra, n), rn1b = cross(p1.rb, n);
      double rn2a = cross(p2.ra, n), rn2b = cross(p2.rb, n);
      double m = a.inv_mass + b.inv_mass;
      double k11 = m + a.inv_inertia * rn1a * rn1a + b.inv_inertia * rn1b * rn1b;
      double k22 = m + a.inv_inertia * rn2a * rn2a + b.inv_inertia * rn2b * rn2b;
      double k12 = m + a.inv_inertia * rn1a * rn2a + b.inv_inertia * rn1b * rn2b;
      double det = k11 * k22 - k12 * k12;
      // Only when K is well conditioned; otherwise the two rows are solved one by one.
      if (k11 * k11 < 1000.0 * det) {
        row.block = true;
        row.k << k11, k12, k12, k22;
        double inv_det = 1.0 / det;
        row.k_inverse << k22 * inv_det, -k12 * inv_det, -k12 * inv_det, k11 * inv_det;
      }
    }
  }
}

void warm_start(SolverScratch& s) {
  for (ContactRow& row : s.rows) {
    SolverBody& a = s.bodies[row.ia];
    SolverBody& b = s.bodies[row.ib];
    const Vec2 t = right_perp(row.normal);
    for (int i = 0; i < row.count; ++i) {
      const ContactPointRow& p = row.points[i];
      apply_impulse(a, b, p, p.normal_impulse * row.normal + p.tangent_impulse * t);
    }
  }
}

// Both normal rows of a two-point manifold as one 2x2 mixed linear complementarity problem,
// solved by enumerating its four cases (Box2D 2.x's block solver): find x >= 0 with
// v = K x + b >= 0 and x_i v_i = 0, where b is the row velocity error at zero impulse.
double solve_block(ContactRow& row, SolverBody& a, SolverBody& b) {
  ContactPointRow& p1 = row.points[0];
  ContactPointRow& p2 = row.points[1];
  const Vec2 n = row.normal;
  Vec2 acc(p1.normal_impulse, p2.normal_impulse);
  Vec2 vn(normal_speed(a, b, p1, n) - p1.target, normal_speed(a, b, p2, n) - p2.target);
  Vec2 rhs = vn - row.k * acc;
  Vec2 x;
  for (;;) {
    x = -(row.k_inverse * rhs);  // both rows active
    if (x.x() >= 0.0 && x.y() >= 0.0) break;
    x = Vec2(-p1.normal_mass * rhs.x(), 0.0);  // only row 1 active
    if (x.x() >= 0.0 && row.k(1, 0) * x.x() + rhs.y() >= 0.0) break;
    x = Vec2(0.0, -p2.normal_mass * rhs.y());  // only row 2 active
    if (x.y() >= 0.0 && row.k(0, 1) * x.y() + rhs.x() >= 0.0) break;
    x = Vec2::Zero();  // neither active
    if (rhs.x() >= 0.0 && rhs.y() >= 0.0) break;
    return 0.0;  // no case fits (rounding); leave the impulses as they are
  }
  Vec2 d = x - acc;
  apply_impulse(a, b, p1, d.x() * n);
  apply_impulse(a, b, p2, d.y() * n);
  p1.normal_impulse = x.x();
  p2.normal_impulse = x.y();
  p1.max_normal_impulse = std::max(p1.max_normal_impulse, x.x());
  p2.max_normal_impulse = std::max(p2.max_normal_impulse, x.y());
  return std::max(std::abs(d.x()), std::abs(d.y()));
}

// One pass over all rows; returns the largest corrective impulse.
double solve_velocity(SolverScratch& s) {
  double largest = 0.0;
  for (ContactRow& row : s.rows) {
    SolverBody& a = s.bodies[row.ia];
    SolverBody& b = s.bodies[row.ib];
    const Vec2 n = row.normal;
    const Vec2 t = right_perp(n);
    // Friction first: the normal rows, solved last, matter more for non-penetration.
    for (int i = 0; i < row.count; ++i) {
      ContactPointRow& p = row.points[i];
      Vec2 dv = b.v + cross(b.w, p.rb) - a.v - cross(a.w, p.ra);
      double lambda = -p.tangent_mass * dot(dv, t);
      double limit = row.friction * p.normal_impulse;
      double acc = std::clamp(p.tangent_impulse + lambda, -limit, limit);
      lambda = acc - p.tangent_impulse;
      p.tangent_impulse = acc;
      apply_impulse(a, b, p, lambda * t);
      largest = std::max(largest, std::abs(lambda));
    }
    if (row.block) {
      largest = std::max(largest, solve_block(row, a, b));
      continue;
    }
    for (int i = 0; i < row.count; ++i) {
      ContactPointRow& p = row.points[i];
      double lambda = -p.normal_mass * (normal_speed(a, b, p, n) - p.target);
      double acc = std::max(p.normal_impulse + lambda, 0.0);
      lambda = acc - p.normal_impulse;
      p.normal_impulse = acc;
      p.max_normal_impulse = std::max(p.max_normal_impulse, acc);
      apply_impulse(a, b, p, lambda * n);
      largest = std::max(largest, std::abs(lambda));
    }
  }
  return largest;
}

// Bounce: points that approached faster than the threshold and carried load leave with
// -e times their approach speed.
void apply_restitution(SolverScratch& s, double threshold) {
  for (ContactRow& row : s.rows) {
    if (row.restitution == 0.0) continue;
    SolverBody& a = s.bodies[row.ia];
    SolverBody& b = s.bodies[row.ib];
    for (int i = 0; i < row.count; ++i) {
      ContactPointRow& p = row.points[i];
      if (p.approach_speed > -threshold || p.max_normal_impulse == 0.0) continue;
      double vn = normal_speed(a, b, p, row.normal);
      double lambda = -p.normal_mass * (vn + row.restitution * p.approach_speed);
      double acc = std::max(p.normal_impulse + lambda, 0.0);
      lambda = acc - p.normal_impulse;
      p.normal_impulse = acc;
      apply_impulse(a, b, p, lambda * row.normal);
    }
  }
}

void store_impulses(WorldImpl& w, const SolverScratch& s) {
  for (const ContactRow& row : s.rows) {
    Manifold& m = w.contacts[row.contact].manifold;
    for (int i = 0; i < row.count; ++i) {
      m.points[i].normal_impulse = row.points[i].normal_impulse;
      m.points[i].tangent_impulse = row.points[i].tangent_impulse;
    }
  }
}

// Split impulses: the position error is removed by impulses on pseudo velocities, which move
// bodies this tick and are then forgotten, so correction adds no momentum.
void solve_position(SolverScratch& s) {
  for (ContactRow& row : s.rows) {
    SolverBody& a = s.bodies[row.ia];
    SolverBody& b = s.bodies[row.ib];
    for (int i = 0; i < row.count; ++i) {
      ContactPointRow& p = row.points[i];
      Vec2 dv = b.pv + cross(b.pw, p.rb) - a.pv - cross(a.pw, p.ra);
      double lambda = -p.normal_mass * (dot(dv, row.normal) - p.pseudo_target);
      double acc = std::max(p.pseudo_impulse + lambda, 0.0);
      lambda = acc - p.pseudo_impulse;
      p.pseudo_impulse = acc;
      Vec2 P = lambda * row.normal;
      a.pv -= a.inv_mass * P;
      a.pw -= a.inv_inertia * cross(p.ra, P);
      b.pv += b.inv_mass * P;
      b.pw += b.inv_inertia * cross(p.rb, P);
    }
  }
}

// Symplectic Euler: x2 = x1 + h (v2 + v_pseudo); rotation by the exact angle h w.
void integrate_positions(WorldImpl& w, const std::vector<int>& awake, SolverScratch& s) {
  const double h = w.settings.dt;
  const double max_speed = w.settings.max_linear_speed;
  for (size_t k = 0; k < awake.size(); ++k) {
    Body& b = w.bodies[awake[k]];
    SolverBody& sb = s.bodies[k + 1];
    double speed2 = length_squared(sb.v);
    if (speed2 > max_speed * max_speed) sb.v *= max_speed / std::sqrt(speed2);
    b.v = sb.v;
    b.w = sb.w;
    b.center += h * (sb.v + sb.pv);
    double turn = h * (sb.w + sb.pw);
    if (turn != 0.0) {
      SinCos sc = det_sincos(turn);
      b.xf.q = mul(Rot{sc.cos, sc.sin}, b.xf.q).normalized();
    }
    b.xf.p = b.center - b.xf.q.rotate(b.local_center);
  }
}

}  // namespace

void WorldImpl::solve(const std::vector<int>& awake) {
  SolverScratch& s = solver_scratch;
  integrate_velocities(*this, awake, s);
  gather_contacts(*this, awake, &s.contacts);
  prepare(*this, s);
  if (settings.warm_starting) warm_start(s);
  for (int it = 0; it < settings.velocity_iterations; ++it) {
    double largest = solve_velocity(s);
    if (largest < settings.early_exit_tolerance) break;
  }
  apply_restitution(s, settings.restitution_threshold);
  store_impulses(*this, s);
  if (settings.split_impulses) {
    for (int it = 0; it < settings.position_iterations; ++it) solve_position(s);
  }
  integrate_positions(*this, awake, s);
}

}  // namespace fulcrum
